"""The original RRLS module path ``rrls.envs.hopper``: code written for it imports unchanged."""

from rrls.envs import ForceHopper, HopperParamsBound, RobustHopper

__all__ = ["HopperParamsBound", "ForceHopper", "RobustHopper"]
