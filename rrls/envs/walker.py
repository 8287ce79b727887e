"""The original RRLS module path ``rrls.envs.walker``: code written for it imports unchanged."""

from rrls.envs import ForceWalker2d, RobustWalker2d, Walker2dParamsBound

__all__ = ["Walker2dParamsBound", "ForceWalker2d", "RobustWalker2d"]
