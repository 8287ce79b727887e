"""Robust-RL wrappers: domain randomization, the adversarial game, action-robust mixing,
disruptors, schedules over time, context in the observation, TC-RMDP's protagonist views."""

from rrls.deprecation import warn_deprecated
from rrls.wrappers.access import ParamsAccess, ParamsForwarding
from rrls.wrappers.action_robust import ConcatenateActions, ProbabilisticActionRobust
from rrls.wrappers.adversarial import DynamicAdversarial
from rrls.wrappers.context import ContextObservation
from rrls.wrappers.disruptors import (
    DISRUPTORS,
    ActionDelay,
    ActionNoise,
    ObservationDelay,
    ObservationDropout,
    ObservationNoise,
    RewardNoise,
    StuckSensors,
    disrupt,
)
from rrls.wrappers.domain_randomization import DomainRandomization
from rrls.wrappers.schedules import (
    SCHEDULES,
    Drift,
    RandomWalk,
    ScheduledParams,
    ScheduleFamily,
    Sinusoid,
    StepChange,
)
from rrls.wrappers.tc_rmdp import ProtagonistObservation, View

#: the original code's misspelt names: deprecated, each access warns (module ``__getattr__``)
_MISSPELT = ("ProbalistActionRobustWrapper", "ProbalisticActionRobust")


def __getattr__(name: str) -> type:
    if name not in _MISSPELT:
        raise AttributeError(f"module 'rrls.wrappers' has no attribute {name!r}")
    warn_deprecated(f"rrls.wrappers.{name} is deprecated; use ProbabilisticActionRobust")
    return ProbabilisticActionRobust


__all__ = [
    "DISRUPTORS",
    "SCHEDULES",
    "ActionDelay",
    "ActionNoise",
    "ContextObservation",
    "Drift",
    "ObservationDelay",
    "ObservationDropout",
    "ObservationNoise",
    "RandomWalk",
    "RewardNoise",
    "ScheduleFamily",
    "ScheduledParams",
    "Sinusoid",
    "StepChange",
    "StuckSensors",
    "disrupt",
    "ConcatenateActions",
    "DomainRandomization",
    "DynamicAdversarial",
    "ParamsAccess",
    "ParamsForwarding",
    "ProbabilisticActionRobust",
    "ProtagonistObservation",
    "View",
]
