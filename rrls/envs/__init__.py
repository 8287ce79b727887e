"""The robust and force environments of every registered task, and their uncertainty sets.

``Robust<Task>`` exposes the masses (and ``worldfriction``) of paper Appendix A and every
further kind of its task table (friction, centre of mass, joints, gears, gravity, timestep);
``Force<Task>`` exposes ``<body>force_x/_y/_z`` external forces. Both are the Gymnasium v5 env
with a ``set_params``/``get_params`` interface on top (see :mod:`rrls.envs.base`); the classes
are class statements filled in from the task declarations (:mod:`rrls.envs.classes`; a task
registered later, :func:`rrls.register_task`, gets its classes made the same way).
``Robust<Task>(paper=True)`` builds ``PaperRobust<Task>``: the paper's physics (the v5 env the
original code built and its writes, :mod:`rrls.envs.paper`) for the paper's six tasks.

>>> from rrls.envs import RobustHopper, HopperParamsBound
>>> env = RobustHopper(torsomass=2.0)
>>> env.get_params()["torsomass"]
2.0
>>> HopperParamsBound.TWO_DIM.value
{'worldfriction': [0.1, 3.0], 'torsomass': [0.1, 3.0]}
"""

from __future__ import annotations

from rrls.envs.classes import (
    ForceAnt,
    ForceHalfCheetah,
    ForceHopper,
    ForceHumanoidStandUp,
    ForceInvertedPendulum,
    ForceWalker2d,
    RobustAnt,
    RobustHalfCheetah,
    RobustHopper,
    RobustHumanoidStandUp,
    RobustInvertedPendulum,
    RobustWalker2d,
)
from rrls.envs.families import FAMILY_ENVS, FORCE_ENVS, ROBUST_ENVS, follow, paper_class
from rrls.envs.sets import (
    ResolvedSet,
    env_class,
    get_uncertainty_set,
    nominal_params,
    resolve,
    training_split,
)
from rrls.tasks import TASKS

follow(globals())  # every registered task's classes and bounds enum, as the table changes

__all__ = [
    "training_split",
    "AntParamsBound",
    "ForceAnt",
    "ForceHalfCheetah",
    "ForceHopper",
    "ForceHumanoidStandUp",
    "ForceInvertedPendulum",
    "ForceWalker2d",
    "HalfCheetahParamsBound",
    "HopperParamsBound",
    "HumanoidStandupParamsBound",
    "InvertedPendulumParamsBound",
    "RobustAnt",
    "RobustHalfCheetah",
    "RobustHopper",
    "RobustHumanoidStandUp",
    "RobustInvertedPendulum",
    "RobustWalker2d",
    "FAMILY_ENVS",
    "FORCE_ENVS",
    "ROBUST_ENVS",
    "ResolvedSet",
    "TASKS",
    "Walker2dParamsBound",
    "env_class",
    "get_uncertainty_set",
    "paper_class",
    "nominal_params",
    "resolve",
]
