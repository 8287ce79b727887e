"""Collection for the doctests of ``rrls/`` (``--doctest-modules``): the Warp twin's modules
import warp, an optional extra; without it they are not collected (tests/test_twin.py skips).
The twin's deprecated module names (aliases that warn on import, no doctests of their own) are
never collected: tests/test_public_api.py imports them on purpose."""

import importlib.util

collect_ignore = ["rrls/twin/check.py", "rrls/twin/tasks.py"]
collect_ignore_glob = (
    []
    if importlib.util.find_spec("warp") and importlib.util.find_spec("mujoco_warp")
    else ["rrls/twin/*"]
)
