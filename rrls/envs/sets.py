"""What a (task, uncertainty set) pair means: its env family, its box with the nominal point
read from the compiled model, its class (:func:`resolve`, the single source of truth), and the
training split rrls can train on."""

from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import Any

import numpy as np

from rrls.envs.families import FAMILY_ENVS, ROBUST_ENVS
from rrls.params import check_bounds
from rrls.tasks import get_task
from rrls.uncertainty import UncertaintySet


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
    "ResolvedSet",
    "env_class",
    "get_uncertainty_set",
    "nominal_params",
    "resolve",
    "training_split",
]
