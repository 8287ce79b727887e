"""The original RRLS module path ``rrls.envs.ant``: code written for it imports unchanged."""

from rrls.envs import AntParamsBound, ForceAnt, RobustAnt

__all__ = ["AntParamsBound", "ForceAnt", "RobustAnt"]
