"""Robust-RL wrappers: domain randomization, the adversarial game, action-robust mixing,
disruptors, schedules over time, context in the observation, TC-RMDP's protagonist views."""

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

#: the original code's (misspelt) names
ProbalistActionRobustWrapper = ProbabilisticActionRobust
ProbalisticActionRobust = ProbabilisticActionRobust

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
    "ProbalistActionRobustWrapper",
    "ProbalisticActionRobust",
    "ProtagonistObservation",
    "View",
]
