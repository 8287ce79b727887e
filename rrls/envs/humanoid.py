"""The original RRLS module path ``rrls.envs.humanoid``: code written for it imports unchanged."""

from rrls.envs import ForceHumanoidStandUp, HumanoidStandupParamsBound, RobustHumanoidStandUp

__all__ = ["HumanoidStandupParamsBound", "ForceHumanoidStandUp", "RobustHumanoidStandUp"]
