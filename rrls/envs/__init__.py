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

import functools
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from enum import Enum
from typing import Any

import numpy as np

from rrls.envs.base import ModifiedParamsMixin
from rrls.envs.classes import (
    BUILT_IN,
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
    class_attributes,
    class_name,
)
from rrls.params import check_bounds
from rrls.registry import on_change
from rrls.tasks import TASKS, TaskSpec, get_task
from rrls.uncertainty import UncertaintySet

_SET_NAMES = {"1d": "ONE_DIM", "2d": "TWO_DIM", "3d": "THREE_DIM", "rarl": "RARL"}

#: (task key, family, paper) -> (the declaration it was built from, the class) of tasks
#: registered beyond the built-in ones; rebuilt when a task is re-registered with ``replace=True``
_CLASSES: dict[tuple[str, str, bool], tuple[TaskSpec, type]] = {}


def _env_class(task: TaskSpec, kind: str, paper: bool = False) -> type:
    """``Robust<Task>`` (kind "robust") or ``Force<Task>`` (kind "force"); ``paper``: its twin
    on the paper's physics. A built-in task's is its class statement (:mod:`rrls.envs.classes`);
    a registered task's is made once from the same attributes."""
    statement = BUILT_IN.get((task.key, kind, paper))
    if statement is not None and statement.task is task:
        return statement
    cached = _CLASSES.get((task.key, kind, paper))
    if cached is not None and cached[0] is task:
        return cached[1]
    name = class_name(task, kind, paper)
    attrs = {**class_attributes(task, kind, paper), "__module__": __name__}
    if task.paper_id is not None and not paper:
        attrs["paper_twin"] = staticmethod(functools.partial(_paper_twin, task.key, kind))
    cls = type(name, (ModifiedParamsMixin, task.base_class(paper)), attrs)
    cls.__qualname__ = name
    _CLASSES[(task.key, kind, paper)] = (task, cls)
    return cls


def _paper_twin(key: str, kind: str) -> type:
    return _env_class(TASKS[key], kind, paper=True)


def paper_class(cls: type) -> type:
    """The twin of an env class on the paper's physics (``PaperRobustHopper`` of
    ``RobustHopper``); a ``ValueError`` for tasks without one."""
    if getattr(cls, "paper", False):
        return cls
    twin = getattr(cls, "paper_twin", None)
    if twin is None:
        raise ValueError(
            f"{cls.__name__} has no paper physics (paper=True is for the paper's six tasks)"
        )
    return twin()


def _bounds_enum(task: TaskSpec) -> type[Enum]:
    members = {
        _SET_NAMES.get(k, k.upper()): {n: [lo, hi] for n, (lo, hi) in bounds.items()}
        for k, bounds in task.sets.items()
    }
    enum = Enum(_enum_name(task), members)
    enum.__module__ = __name__
    return enum


def _enum_name(task: TaskSpec) -> str:
    return f"{task.name.replace('StandUp', 'Standup')}ParamsBound"


class _Classes(Mapping):
    """``{task key: env class}`` of one family over every registered task."""

    def __init__(self, kind: str) -> None:
        self.kind = kind

    def __getitem__(self, key: str) -> type:
        task = TASKS.get(key)
        if task is None:
            raise KeyError(key)
        if self.kind == "force" and not task.forces:
            raise KeyError(f"task {key!r} declares no forces")
        return _env_class(task, self.kind)

    def __iter__(self) -> Iterator[str]:
        return iter([k for k, t in TASKS.items() if self.kind == "robust" or t.forces])

    def __len__(self) -> int:
        return sum(1 for _ in self)


ROBUST_ENVS: Mapping[str, type] = _Classes("robust")
FORCE_ENVS: Mapping[str, type] = _Classes("force")

#: the names :func:`_publish` made attributes of this module, per task key
_PUBLISHED: dict[str, list[str]] = {}


def _publish(key: str) -> None:
    """Keep this module's ``Robust<Task>``, ``Force<Task>``, ``Paper...`` and
    ``<Task>ParamsBound`` attributes in step with the task table (registered by
    ``rrls.registry.on_change``), so a task registered later imports, pickles and unpickles its
    classes by name like the built-ins."""
    space = globals()
    for name in _PUBLISHED.pop(key, []):
        space.pop(name, None)
    task = TASKS.get(key)
    if task is None:
        return
    classes = [_env_class(task, "robust")]
    if task.forces:
        classes.append(_env_class(task, "force"))
    if task.paper_id is not None:
        classes += [
            _env_class(task, k, paper=True)
            for k in ("robust", "force")
            if k != "force" or task.forces
        ]
    enum = _bounds_enum(task)
    named = {cls.__name__: cls for cls in classes} | {enum.__name__: enum}
    space.update(named)
    _PUBLISHED[key] = list(named)


for _key in list(TASKS):
    _publish(_key)
on_change(_publish)


FAMILY_ENVS: dict[str, Mapping[str, type]] = {"robust": ROBUST_ENVS, "force": FORCE_ENVS}


@functools.cache
def _nominal(cls: type) -> tuple[tuple[str, float], ...]:
    env = cls()
    try:
        return tuple(env.get_params(kinds="all").items())
    finally:
        env.close()


def nominal_params(task: str, kind: str = "robust") -> dict[str, float]:
    """The unmodified model's parameter values, read from the compiled MuJoCo model.

    Read once per (task, family) and cached immutably: each call returns a fresh dict.
    """
    if kind not in FAMILY_ENVS:
        raise ValueError(f"unknown env family {kind!r}; valid: {', '.join(FAMILY_ENVS)}")
    return dict(_nominal(FAMILY_ENVS[kind][get_task(task).key]))


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


def training_split(task: str, uncertainty: str, text: str) -> str:
    """``text`` checked as a split of the set rrls can train on, in its canonical form
    (``extrapolation:0.5``): interpolation's training part (the set minus an interior box) is
    not a box, which M2TD3's and RARL's searches need, so training refuses it."""
    from rrls.uncertainty import Split

    box = get_uncertainty_set(task, uncertainty)
    if box.dim == 0:
        raise ValueError(f"split {text!r}: the set {uncertainty!r} of {task!r} is empty")
    split = Split.parse(box, text)
    if split.kind != "extrapolation":
        raise ValueError(
            f"split {text!r}: training takes extrapolation[:F] (an inner box); interpolation's "
            "training part is not a box (evaluate(..., split=Split.interpolation(...)) and "
            "DomainRandomization(randomize_fn=split.sample_train) serve it by hand)"
        )
    width = (split.region.high - split.region.low) / (box.high - box.low)
    return f"extrapolation:{float(round(float(width.max()), 6)):g}"


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
