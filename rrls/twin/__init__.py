"""MuJoCo Warp twins of rrls's tasks: a parameter point per world, on a GPU, for training.

Needs the ``warp`` extra (``warp-lang`` and ``mujoco-warp``; in the checkout:
``python3 -m pip install -c constraints.txt ".[warp]"``);
importing this package does not import warp (making a ``WarpTwin`` does). Evaluation stays on
CPU MuJoCo. See :class:`WarpTwin`; ``rrls train --simulator warp`` trains on it.
"""

from __future__ import annotations

from rrls.deprecation import moved_modules
from rrls.twin.catalog import DIVERGES, REFUSED, TWIN_TASKS, TwinTask
from rrls.twin.env import WarpTwin

__all__ = ["DIVERGES", "REFUSED", "TWIN_TASKS", "TwinTask", "WarpTwin"]

#: modules renamed so as not to repeat top-level names (``rrls.tasks``, ``rrls.check``): the
#: old paths still import, and warn
__getattr__ = moved_modules(
    {"rrls.twin.tasks": "rrls.twin.catalog", "rrls.twin.check": "rrls.twin.agreement"}
)
