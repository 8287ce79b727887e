"""The original RRLS module path ``rrls.wrappers.probabilistic_action_robust``."""

from rrls.wrappers.action_robust import ProbabilisticActionRobust

#: the original code's (misspelt) class name
ProbalisticActionRobust = ProbabilisticActionRobust

__all__ = ["ProbabilisticActionRobust", "ProbalisticActionRobust"]
