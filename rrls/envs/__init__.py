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
from dataclasses import dataclass
from enum import Enum
from typing import Any

import numpy as np
from gymnasium.envs.mujoco.ant_v5 import AntEnv
from gymnasium.envs.mujoco.half_cheetah_v5 import HalfCheetahEnv
from gymnasium.envs.mujoco.hopper_v5 import HopperEnv
from gymnasium.envs.mujoco.humanoidstandup_v5 import HumanoidStandupEnv
from gymnasium.envs.mujoco.inverted_pendulum_v5 import InvertedPendulumEnv
from gymnasium.envs.mujoco.walker2d_v5 import Walker2dEnv

from rrls.envs.base import ModifiedParamsMixin
from rrls.params import check_bounds
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


FAMILY_ENVS: dict[str, dict[str, type]] = {"robust": ROBUST_ENVS, "force": FORCE_ENVS}


@functools.cache
def _nominal(key: str, family: str) -> tuple[tuple[str, float], ...]:
    env = FAMILY_ENVS[family][key]()
    try:
        return tuple(env.get_params().items())
    finally:
        env.close()


def nominal_params(task: str, kind: str = "robust") -> dict[str, float]:
    """The unmodified model's parameter values, read from the compiled MuJoCo model.

    Read once per (task, family) and cached immutably: each call returns a fresh dict.
    """
    if kind not in FAMILY_ENVS:
        raise ValueError(f"unknown env family {kind!r}; valid: {', '.join(FAMILY_ENVS)}")
    return dict(_nominal(get_task(task).key, kind))


def get_uncertainty_set(task: str, name: str = "3d") -> UncertaintySet:
    """The paper's uncertainty set ``name`` (``1d``, ``2d``, ``3d``, ``rarl``; ``nominal``: the
    zero-dimensional set of the unmodified model) of ``task``, with its family and nominal point."""
    spec = get_task(task)
    key = str(name).lower()
    if key == "nominal":
        return resolve(spec.key, key).box  # zero-dimensional: the model as shipped
    if key not in spec.sets:
        raise ValueError(
            f"task {spec.key!r} has no uncertainty set {name!r}; "
            f"valid: {', '.join([*spec.sets, 'nominal'])}"
        )
    family = spec.families[key]
    return UncertaintySet.from_bounds(
        dict(spec.sets[key]), nominal_params(spec.key, family), f"{spec.key}/{key}", family
    )


@dataclass(frozen=True)
class ResolvedSet:
    """What a (task, uncertainty set) pair means: which env family, which box, which class.

    ``name`` is the set's name (``"3d"``, ``"rarl"``, ``"nominal"``) or None for a user-built
    box; ``box`` is zero-dimensional for ``"nominal"`` (the model exactly as Gymnasium ships it);
    ``box.nominal`` is always filled in.
    """

    task: str
    name: str | None
    family: str
    box: UncertaintySet
    env_class: type

    @property
    def is_nominal(self) -> bool:
        return self.box.dim == 0

    @property
    def label(self) -> str:
        return self.box.label or f"{self.task}/{self.name or 'custom'}"

    def make_env(self, **kwargs: Any) -> Any:
        """A bare (unwrapped, no time limit) env of the set's family."""
        return self.env_class(**kwargs)


def resolve(task: str, uncertainty: str | UncertaintySet = "3d") -> ResolvedSet:
    """The single source of truth mapping (task, set name or ``UncertaintySet``) to its env.

    Named sets carry their family in the task table (``rarl``: ``Force<Task>``, the others
    ``Robust<Task>``); a user-built set uses its ``family`` if given, else the family whose
    parameter table holds all its names. Unknown tasks, sets or names raise a ``ValueError``
    listing the valid ones.
    """
    spec = get_task(task)
    key = spec.key
    if isinstance(uncertainty, UncertaintySet):
        box = uncertainty
        family = box.family or spec.family_of(box.names)
        if box.family is not None and spec.family_of(box.names) != family and box.dim:
            raise ValueError(
                f"set {box.label or list(box.names)} is marked {family!r} but names "
                f"{spec.family_of(box.names)!r} parameters of task {key!r}"
            )
        cls = FAMILY_ENVS[family][key]
        box = UncertaintySet(
            box.names,
            box.low,
            box.high,
            _nominal_of(key, family, box),
            box.label,
            family,
        )
        check_bounds(cls.param_specs, box)
        return ResolvedSet(key, None, family, box, cls)
    if not isinstance(uncertainty, str):
        raise TypeError(
            f"uncertainty must be a set name or an UncertaintySet, got {type(uncertainty).__name__}"
        )
    name = uncertainty.lower()
    if name == "nominal":
        box = UncertaintySet((), [], [], [], f"{key}/nominal", "robust")
        return ResolvedSet(key, name, "robust", box, ROBUST_ENVS[key])
    box = get_uncertainty_set(key, name)
    return ResolvedSet(key, name, box.family, box, FAMILY_ENVS[box.family][key])


def _nominal_of(key: str, family: str, box: UncertaintySet) -> np.ndarray:
    if box.nominal is not None:
        return box.nominal
    nominal = nominal_params(key, family)
    canonical = FAMILY_ENVS[family][key]._names()
    return np.array([nominal[canonical[n]] for n in box.names], dtype=np.float64)


def env_class(task: str, uncertainty: str | UncertaintySet = "3d") -> type:
    """The env class an uncertainty set acts on (see :func:`resolve`)."""
    return resolve(task, uncertainty).env_class


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
    "FAMILY_ENVS",
    "FORCE_ENVS",
    "ROBUST_ENVS",
    "ResolvedSet",
    "TASKS",
    "Walker2dParamsBound",
    "env_class",
    "get_uncertainty_set",
    "nominal_params",
    "resolve",
]
