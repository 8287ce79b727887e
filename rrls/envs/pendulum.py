"""The original RRLS module path ``rrls.envs.pendulum``: code written for it imports unchanged."""

from rrls.envs import ForceInvertedPendulum, InvertedPendulumParamsBound, RobustInvertedPendulum

__all__ = ["InvertedPendulumParamsBound", "ForceInvertedPendulum", "RobustInvertedPendulum"]
