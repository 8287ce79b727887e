"""Evaluation meshes: uniform grids over an uncertainty set (paper §4, "Evaluation Procedure").

Points are plain arrays; environments are built only when asked for, one at a time
(the original code built 5 660 of them at import).

>>> from rrls.evaluation import evaluation_points
>>> evaluation_points("hopper", "2d", mesh=3).shape
(9, 2)
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, MutableSequence, Sequence
from typing import Any

import numpy as np

from rrls.deprecation import renamed_keywords
from rrls.interface import all_params
from rrls.uncertainty import UncertaintySet

Bounds = Mapping[str, Sequence[float]] | UncertaintySet


def resolve_uncertainty(task: str, uncertainty: str | UncertaintySet) -> UncertaintySet:
    """The box of a set name (``1d``, ``2d``, ``3d``, ``rarl``, ``nominal``) or a user box.

    ``"nominal"`` is zero-dimensional: the model exactly as Gymnasium ships it (see
    :func:`rrls.envs.resolve`, the one place that maps names to sets and env families).
    """
    from rrls.envs import resolve

    return resolve(task, uncertainty).box


@renamed_keywords(nb_mesh_dim="mesh")
def evaluation_points(
    task: str,
    uncertainty: str | UncertaintySet = "3d",
    mesh: int = 10,
    endpoint: bool = True,
) -> np.ndarray:
    """The mesh of ``task``'s set as an ``(mesh ** d, d)`` array (no env is built)."""
    box = resolve_uncertainty(task, uncertainty)
    return box.mesh(mesh, endpoint=endpoint)


class _Lazy:
    """A not-yet-built env of an :class:`EvaluationSet`: ``factory(**params)`` on access."""

    __slots__ = ("factory", "params")

    def __init__(self, factory: Callable[..., Any], params: dict[str, float]) -> None:
        self.factory = factory
        self.params = params


class EvaluationSet(MutableSequence):
    """A lazy list of environments, one per mesh point: ``modified_env(**point)``.

    Behaves like the original's list — ``len``, indexing, iteration, ``+`` with another list or
    set, ``random.shuffle``, assignment, ``append`` — but an element is built only when it is
    read (a new env at each read until something is stored in its place). ``points`` holds the
    mesh as an array, ``params(i)`` the i-th point as a dict.
    """

    def __init__(
        self, modified_env: Callable[..., Any], box: UncertaintySet, points: np.ndarray
    ) -> None:
        self.modified_env = modified_env
        self.uncertainty_set = box
        self._slots: list[Any] = [_Lazy(modified_env, box.to_dict(p)) for p in points]

    @classmethod
    def _of(cls, template: EvaluationSet, slots: list[Any]) -> EvaluationSet:
        out = cls.__new__(cls)
        out.modified_env, out.uncertainty_set, out._slots = (
            template.modified_env,
            template.uncertainty_set,
            slots,
        )
        return out

    @property
    def points(self) -> np.ndarray:
        """The mesh points of the (not replaced) elements, ordered like ``names``."""
        rows = [self.uncertainty_set.to_array(self.params(i)) for i in range(len(self))]
        return np.array(rows, dtype=np.float64).reshape(len(rows), self.uncertainty_set.dim)

    def params(self, i: int) -> dict[str, float]:
        slot = self._slots[i]
        if isinstance(slot, _Lazy):
            return dict(slot.params)
        return dict(all_params(slot))

    def __len__(self) -> int:
        return len(self._slots)

    def __getitem__(self, i):  # Sequence protocol
        if isinstance(i, slice):
            return self._of(self, self._slots[i])
        slot = self._slots[i]
        return slot.factory(**slot.params) if isinstance(slot, _Lazy) else slot

    def __setitem__(self, i, value) -> None:  # MutableSequence protocol
        if isinstance(i, slice):
            value = value._slots if isinstance(value, EvaluationSet) else list(value)
        self._slots[i] = value

    def __delitem__(self, i) -> None:  # MutableSequence protocol
        del self._slots[i]

    def insert(self, index: int, value: Any) -> None:
        self._slots.insert(index, value)

    def __add__(self, other: Any) -> EvaluationSet:
        if isinstance(other, EvaluationSet):
            return self._of(self, self._slots + other._slots)
        if isinstance(other, (list, tuple)):
            return self._of(self, self._slots + list(other))
        return NotImplemented

    def __radd__(self, other: Any) -> EvaluationSet:
        if isinstance(other, (list, tuple)):
            return self._of(self, list(other) + self._slots)
        return NotImplemented

    def __repr__(self) -> str:
        name = getattr(self.modified_env, "__name__", repr(self.modified_env))
        return f"EvaluationSet({name}, {self.uncertainty_set!r}, {len(self)} points)"


@renamed_keywords(nb_mesh_dim="mesh")
def generate_evaluation_set(
    modified_env: Callable[..., Any],
    param_bounds: Bounds,
    mesh: int = 10,
    endpoint: bool = True,
) -> EvaluationSet:
    """Environments on a uniform mesh over ``param_bounds`` (the original signature).

    ``endpoint=True`` (default) includes both bounds; ``endpoint=False`` reproduces the original
    code's ``np.arange`` mesh exactly. The result is lazy: environments are built on access.
    ``mesh`` is points per dimension (the original's ``nb_mesh_dim=``, deprecated, still works).

    >>> from rrls import generate_evaluation_set
    >>> from rrls.envs import RobustHopper, HopperParamsBound
    >>> envs = generate_evaluation_set(RobustHopper, HopperParamsBound.TWO_DIM.value, 10)
    >>> len(envs), envs.params(len(envs) - 1)
    (100, {'worldfriction': 3.0, 'torsomass': 3.0})
    >>> envs[0].get_params()["worldfriction"]
    0.1
    """
    from rrls.params import check_bounds

    box = UncertaintySet.from_bounds(param_bounds)
    check_bounds(getattr(modified_env, "param_specs", ()), box)  # refuse now, not at env build
    return EvaluationSet(modified_env, box, box.mesh(mesh, endpoint=endpoint))


@renamed_keywords(nb_mesh_dim="mesh")
def default_evaluation_set(task: str, uncertainty: str = "3d", mesh: int = 10) -> EvaluationSet:
    """The paper's evaluation set of ``task`` over ``uncertainty`` (10 points per dimension)."""
    from rrls.envs import resolve

    resolved = resolve(task, uncertainty)
    return EvaluationSet(resolved.env_class, resolved.box, resolved.box.mesh(mesh))


__all__ = [
    "Bounds",
    "default_evaluation_set",
    "evaluation_points",
    "EvaluationSet",
    "generate_evaluation_set",
    "resolve_uncertainty",
]
