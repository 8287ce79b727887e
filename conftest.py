"""Collection for the doctests of ``rrls/`` (``--doctest-modules``): the Warp twin's modules
import warp, an optional extra; without it they are not collected (tests/test_twin.py skips)."""

import importlib.util

collect_ignore_glob = (
    []
    if importlib.util.find_spec("warp") and importlib.util.find_spec("mujoco_warp")
    else ["rrls/twin/*"]
)
