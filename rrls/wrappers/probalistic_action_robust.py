"""The original RRLS module path ``rrls.wrappers.probalistic_action_robust`` (sic)."""

from rrls.wrappers.action_robust import ProbabilisticActionRobust

#: the original code's (misspelt) class name
ProbalisticActionRobust = ProbabilisticActionRobust

__all__ = ["ProbabilisticActionRobust", "ProbalisticActionRobust"]
