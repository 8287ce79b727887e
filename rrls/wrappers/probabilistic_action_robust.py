"""The original RRLS module path ``rrls.wrappers.probabilistic_action_robust``."""

from __future__ import annotations

from rrls.deprecation import warn_deprecated
from rrls.wrappers.action_robust import ProbabilisticActionRobust


def __getattr__(name: str) -> type:
    if name != "ProbalisticActionRobust":  # the original's misspelt class name: deprecated
        raise AttributeError(
            f"module 'rrls.wrappers.probabilistic_action_robust' has no attribute {name!r}"
        )
    warn_deprecated(f"{__name__}.{name} is deprecated; use ProbabilisticActionRobust")
    return ProbabilisticActionRobust


__all__ = ["ProbabilisticActionRobust"]
