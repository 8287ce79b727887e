"""The robust and force environments of every registered task, and their uncertainty sets.

``Robust<Task>`` exposes the masses (and ``worldfriction``) of paper Appendix A and every
further kind of its task table (friction, centre of mass, joints, gears, gravity, timestep);
``Force<Task>`` exposes ``<body>force_x/_y/_z`` external forces. Both are the Gymnasium v5 env
with a ``set_params``/``get_params`` interface on top (see :mod:`rrls.envs.base`); the classes
are built from the task declarations (:func:`rrls.register_task`) on first use.
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
from rrls.envs.paper import paper_specs
from rrls.params import check_bounds
from rrls.tasks import TASKS, TaskSpec, get_task
from rrls.uncertainty import UncertaintySet

_SET_NAMES = {"1d": "ONE_DIM", "2d": "TWO_DIM", "3d": "THREE_DIM", "rarl": "RARL"}

#: (task key, family, paper) -> (the declaration it was built from, the class); rebuilt when a
#: task is re-registered with ``replace=True``
_CLASSES: dict[tuple[str, str, bool], tuple[TaskSpec, type]] = {}


def _env_class(task: TaskSpec, kind: str, paper: bool = False) -> type:
    """``Robust<Task>`` (kind "robust") or ``Force<Task>`` (kind "force"), built once per task;
    ``paper``: ``PaperRobust<Task>``/``PaperForce<Task>`` on the paper's physics (the original's
    v5 env and writes: :mod:`rrls.envs.paper`), what ``Robust<Task>(paper=True)`` builds."""
    cached = _CLASSES.get((task.key, kind, paper))
    if cached is not None and cached[0] is task:
        return cached[1]
    if paper:
        specs = paper_specs(task, kind)
    else:
        specs = task.params if kind == "robust" else task.forces
    name = f"{'Paper' if paper else ''}{kind.capitalize()}{task.name}"
    what = "physical parameters" if kind == "robust" else "external forces (world frame, N)"
    masses = [s.name for s in specs if s.field in ("body_mass", "xfrc_applied")]
    first = masses[-1] if masses else specs[-1].name if specs else None
    example = (
        f"""
    >>> from rrls.envs import {name}
    >>> env = {name}({first}=1.5)
    >>> obs, info = env.reset(seed=0)
    >>> info["{first}"]
    1.5
    >>> env.set_params({first}=0.5)
    >>> env.get_params()["{first}"]
    0.5
    """
        if task.key in _DOCTESTED and first and not paper
        else ""
    )
    base = task.base_class(paper)
    built_on = task.paper_id if paper else task.v5_id or base.__name__
    doc = f"""Gymnasium's ``{built_on}`` whose {what} can be read and changed.

    Parameters: {", ".join(s.name for s in specs)}.
    {example}"""
    attrs: dict[str, Any] = {"task": task, "param_specs": specs, "__doc__": doc}
    attrs.update(__module__=__name__, paper=paper)
    if task.paper_id is not None and not paper:
        attrs["paper_twin"] = staticmethod(functools.partial(_paper_twin, task.key, kind))
    cls = type(name, (ModifiedParamsMixin, base), attrs)
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


#: the tasks whose class docstrings carry a doctest (the paper's six: one example per kind)
_DOCTESTED = ("ant", "halfcheetah", "hopper", "humanoidstandup", "invertedpendulum", "walker")


def _bounds_enum(task: TaskSpec) -> type[Enum]:
    members = {
        _SET_NAMES.get(k, k.upper()): {n: [lo, hi] for n, (lo, hi) in bounds.items()}
        for k, bounds in task.sets.items()
    }
    enum = Enum(f"{task.name.replace('StandUp', 'Standup')}ParamsBound", members)
    enum.__module__ = __name__
    return enum


_ENUMS: dict[str, tuple[TaskSpec, type[Enum]]] = {}


class _Classes(Mapping):
    """``{task key: env class}`` of one family over every registered task (built on demand)."""

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

RobustAnt = ROBUST_ENVS["ant"]
RobustHalfCheetah = ROBUST_ENVS["halfcheetah"]
RobustHopper = ROBUST_ENVS["hopper"]
RobustHumanoidStandUp = ROBUST_ENVS["humanoidstandup"]
RobustInvertedPendulum = ROBUST_ENVS["invertedpendulum"]
RobustWalker2d = ROBUST_ENVS["walker"]

ForceAnt = FORCE_ENVS["ant"]
ForceHalfCheetah = FORCE_ENVS["halfcheetah"]
ForceHopper = FORCE_ENVS["hopper"]
ForceHumanoidStandUp = FORCE_ENVS["humanoidstandup"]
ForceInvertedPendulum = FORCE_ENVS["invertedpendulum"]
ForceWalker2d = FORCE_ENVS["walker"]

AntParamsBound = _bounds_enum(TASKS["ant"])
HalfCheetahParamsBound = _bounds_enum(TASKS["halfcheetah"])
HopperParamsBound = _bounds_enum(TASKS["hopper"])
HumanoidStandupParamsBound = _bounds_enum(TASKS["humanoidstandup"])
InvertedPendulumParamsBound = _bounds_enum(TASKS["invertedpendulum"])
Walker2dParamsBound = _bounds_enum(TASKS["walker"])


def __getattr__(name: str) -> Any:
    """``Robust<Name>``, ``Force<Name>`` and ``<Name>ParamsBound`` of any registered task (so
    classes of tasks registered later import, pickle and unpickle by name like the built-ins)."""
    for task in list(TASKS.values()):
        if name == f"Robust{task.name}":
            return ROBUST_ENVS[task.key]
        if name == f"Force{task.name}" and task.forces:
            return FORCE_ENVS[task.key]
        if name in (f"PaperRobust{task.name}", f"PaperForce{task.name}") and task.paper_id:
            return _env_class(task, "robust" if "Robust" in name else "force", paper=True)
        if name == f"{task.name}ParamsBound".replace("StandUp", "Standup"):
            cached = _ENUMS.get(task.key)
            if cached is None or cached[0] is not task:
                _ENUMS[task.key] = cached = (task, _bounds_enum(task))
            return cached[1]
    raise AttributeError(f"module 'rrls.envs' has no attribute {name!r}")


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
