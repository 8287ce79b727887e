"""The robust and force environments of the six tasks, and their uncertainty sets.

``Robust<Task>`` exposes the masses (and ``worldfriction``) of paper Appendix A; ``Force<Task>``
exposes ``<body>force_x/_y/_z`` external forces. Both are the Gymnasium v5 env with a
``set_params``/``get_params`` interface on top (see :mod:`rrls.envs.base`).

>>> from rrls.envs import RobustHopper, HopperParamsBound
>>> env = RobustHopper(torsomass=2.0)
>>> env.get_params()["torsomass"]
2.0
>>> HopperParamsBound.TWO_DIM.value
{'worldfriction': [0.1, 3.0], 'torsomass': [0.1, 3.0]}
"""

from __future__ import annotations

import functools
from enum import Enum
from typing import Any

from gymnasium.envs.mujoco.ant_v5 import AntEnv
from gymnasium.envs.mujoco.half_cheetah_v5 import HalfCheetahEnv
from gymnasium.envs.mujoco.hopper_v5 import HopperEnv
from gymnasium.envs.mujoco.humanoidstandup_v5 import HumanoidStandupEnv
from gymnasium.envs.mujoco.inverted_pendulum_v5 import InvertedPendulumEnv
from gymnasium.envs.mujoco.walker2d_v5 import Walker2dEnv

from rrls.envs.base import ModifiedParamsMixin
from rrls.tasks import TASKS, TaskSpec, get_task
from rrls.uncertainty import UncertaintySet

_BASES = {
    "ant": AntEnv,
    "halfcheetah": HalfCheetahEnv,
    "hopper": HopperEnv,
    "humanoidstandup": HumanoidStandupEnv,
    "invertedpendulum": InvertedPendulumEnv,
    "walker": Walker2dEnv,
}

_SET_NAMES = {"1d": "ONE_DIM", "2d": "TWO_DIM", "3d": "THREE_DIM", "rarl": "RARL"}


def _env_class(task: TaskSpec, kind: str) -> type:
    """``Robust<Task>`` (kind "robust") or ``Force<Task>`` (kind "force")."""
    specs = task.params if kind == "robust" else task.forces
    name = f"{kind.capitalize()}{task.name}"
    what = "physical parameters" if kind == "robust" else "external forces (world frame, N)"
    first = specs[-1].name
    doc = f"""Gymnasium's ``{task.v5_id}`` whose {what} can be read and changed.

    Parameters: {", ".join(s.name for s in specs)}.

    >>> from rrls.envs import {name}
    >>> env = {name}({first}=1.5)
    >>> obs, info = env.reset(seed=0)
    >>> info["{first}"]
    1.5
    >>> env.set_params({first}=0.5)
    >>> env.get_params()["{first}"]
    0.5
    """
    cls = type(
        name,
        (ModifiedParamsMixin, _BASES[task.key]),
        {"task": task, "param_specs": specs, "__doc__": doc, "__module__": __name__},
    )
    cls.__qualname__ = name
    return cls


def _bounds_enum(task: TaskSpec) -> type[Enum]:
    members = {
        _SET_NAMES[k]: {n: [lo, hi] for n, (lo, hi) in bounds.items()}
        for k, bounds in task.sets.items()
    }
    enum = Enum(f"{task.name.replace('StandUp', 'Standup')}ParamsBound", members)
    enum.__module__ = __name__
    return enum


RobustAnt = _env_class(TASKS["ant"], "robust")
RobustHalfCheetah = _env_class(TASKS["halfcheetah"], "robust")
RobustHopper = _env_class(TASKS["hopper"], "robust")
RobustHumanoidStandUp = _env_class(TASKS["humanoidstandup"], "robust")
RobustInvertedPendulum = _env_class(TASKS["invertedpendulum"], "robust")
RobustWalker2d = _env_class(TASKS["walker"], "robust")

ForceAnt = _env_class(TASKS["ant"], "force")
ForceHalfCheetah = _env_class(TASKS["halfcheetah"], "force")
ForceHopper = _env_class(TASKS["hopper"], "force")
ForceHumanoidStandUp = _env_class(TASKS["humanoidstandup"], "force")
ForceInvertedPendulum = _env_class(TASKS["invertedpendulum"], "force")
ForceWalker2d = _env_class(TASKS["walker"], "force")

AntParamsBound = _bounds_enum(TASKS["ant"])
HalfCheetahParamsBound = _bounds_enum(TASKS["halfcheetah"])
HopperParamsBound = _bounds_enum(TASKS["hopper"])
HumanoidStandupParamsBound = _bounds_enum(TASKS["humanoidstandup"])
InvertedPendulumParamsBound = _bounds_enum(TASKS["invertedpendulum"])
Walker2dParamsBound = _bounds_enum(TASKS["walker"])

ROBUST_ENVS: dict[str, type] = {
    "ant": RobustAnt,
    "halfcheetah": RobustHalfCheetah,
    "hopper": RobustHopper,
    "humanoidstandup": RobustHumanoidStandUp,
    "invertedpendulum": RobustInvertedPendulum,
    "walker": RobustWalker2d,
}
FORCE_ENVS: dict[str, type] = {
    "ant": ForceAnt,
    "halfcheetah": ForceHalfCheetah,
    "hopper": ForceHopper,
    "humanoidstandup": ForceHumanoidStandUp,
    "invertedpendulum": ForceInvertedPendulum,
    "walker": ForceWalker2d,
}


def env_class(task: str, uncertainty: str = "3d") -> type:
    """The env class an uncertainty set acts on: ``Force<Task>`` for ``"rarl"``, else ``Robust``."""
    key = get_task(task).key
    return FORCE_ENVS[key] if uncertainty == "rarl" else ROBUST_ENVS[key]


@functools.cache
def nominal_params(task: str, kind: str = "robust") -> dict[str, float]:
    """The unmodified model's parameter values, read from the compiled MuJoCo model."""
    key = get_task(task).key
    env = (ROBUST_ENVS if kind == "robust" else FORCE_ENVS)[key]()
    try:
        return env.get_params()
    finally:
        env.close()


def get_uncertainty_set(task: str, name: str = "3d") -> UncertaintySet:
    """The paper's uncertainty set ``name`` (``1d``, ``2d``, ``3d`` or ``rarl``) of ``task``."""
    spec = get_task(task)
    key = name.lower()
    if key not in spec.sets:
        raise ValueError(
            f"task {spec.key!r} has no uncertainty set {name!r}; valid: {', '.join(spec.sets)}"
        )
    nominal = nominal_params(spec.key, "force" if key == "rarl" else "robust")
    return UncertaintySet.from_bounds(dict(spec.sets[key]), nominal, label=f"{spec.key}/{key}")


def make_env(task: str, uncertainty: str = "3d", **kwargs: Any):
    """A bare (unwrapped, no time limit) robust or force env of ``task``."""
    return env_class(task, uncertainty)(**kwargs)


__all__ = [
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
    "TASKS",
    "Walker2dParamsBound",
    "env_class",
    "get_uncertainty_set",
    "nominal_params",
]
