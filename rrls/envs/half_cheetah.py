"""The original RRLS module path ``rrls.envs.half_cheetah``: imports unchanged."""

from rrls.envs import ForceHalfCheetah, HalfCheetahParamsBound, RobustHalfCheetah

__all__ = ["HalfCheetahParamsBound", "ForceHalfCheetah", "RobustHalfCheetah"]
