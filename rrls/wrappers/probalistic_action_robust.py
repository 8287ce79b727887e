"""The original RRLS module path ``rrls.wrappers.probalistic_action_robust`` (sic), deprecated:
use ``rrls.wrappers.ProbabilisticActionRobust``. Each name warns (``DeprecationWarning``)."""

from __future__ import annotations

from typing import Any

from rrls.deprecation import warn_deprecated
from rrls.wrappers import action_robust

#: the original's names; the module keeps no global of them, so every access warns
_NAMES = ("ProbabilisticActionRobust", "ProbalisticActionRobust")


def __getattr__(name: str) -> Any:
    if name not in _NAMES:
        raise AttributeError(
            f"module 'rrls.wrappers.probalistic_action_robust' has no attribute {name!r}"
        )
    warn_deprecated(
        f"rrls.wrappers.probalistic_action_robust.{name} is deprecated; use "
        "rrls.wrappers.ProbabilisticActionRobust"
    )
    return action_robust.ProbabilisticActionRobust


__all__ = list(_NAMES)
