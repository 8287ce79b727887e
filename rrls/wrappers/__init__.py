"""Robust-RL wrappers: domain randomization, the adversarial game, action-robust mixing."""

from rrls.wrappers.access import ParamsAccess, ParamsForwarding
from rrls.wrappers.action_robust import ConcatenateActions, ProbabilisticActionRobust
from rrls.wrappers.adversarial import DynamicAdversarial
from rrls.wrappers.domain_randomization import DomainRandomization

#: the original code's (misspelt) names
ProbalistActionRobustWrapper = ProbabilisticActionRobust
ProbalisticActionRobust = ProbabilisticActionRobust

__all__ = [
    "ConcatenateActions",
    "DomainRandomization",
    "DynamicAdversarial",
    "ParamsAccess",
    "ParamsForwarding",
    "ProbabilisticActionRobust",
    "ProbalistActionRobustWrapper",
    "ProbalisticActionRobust",
]
