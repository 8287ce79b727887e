"""The env classes of every registered task, by family: ``Robust<Task>`` (physical parameters)
and ``Force<Task>`` (external forces), their twins on the paper's physics, and each task's
``<Task>ParamsBound`` enum of its sets (the original code's names).

A built-in task's classes are its class statements (:mod:`rrls.envs.classes`); a task registered
later (:func:`rrls.register_task`) gets its classes made once from the same attributes, and
the ``rrls.envs`` namespace follows the task table (:func:`follow`), so they import and pickle
by name like the built-ins.
"""

from __future__ import annotations

import functools
from collections.abc import Iterator, Mapping
from enum import Enum
from typing import Any

from rrls.envs.base import ModifiedParamsMixin
from rrls.envs.classes import BUILT_IN, class_attributes, class_name
from rrls.registry import on_change
from rrls.tasks import TASKS, TaskSpec

#: where a registered task's classes live (and pickle by name): the package's namespace
PACKAGE = "rrls.envs"

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
    attrs = {**class_attributes(task, kind, paper), "__module__": PACKAGE}
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
    enum = Enum(f"{task.name.replace('StandUp', 'Standup')}ParamsBound", members)
    enum.__module__ = PACKAGE
    return enum


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

#: the names :func:`_publish` put in the followed namespaces, per task key
_PUBLISHED: dict[str, list[str]] = {}
#: the namespaces that follow the task table (``rrls.envs``'s: :func:`follow`)
_NAMESPACES: list[dict[str, Any]] = []


def follow(namespace: dict[str, Any]) -> None:
    """Keep ``namespace`` (the ``rrls.envs`` package's) holding every registered task's
    ``Robust<Task>``, ``Force<Task>``, ``Paper...`` classes and ``<Task>ParamsBound``, in step
    with the task table (``rrls.registry.on_change``): a task registered later imports, pickles
    and unpickles its classes by name like the built-ins, and an unregistered one's are gone."""
    _NAMESPACES.append(namespace)
    for key in list(TASKS):
        _publish(key)


def _publish(key: str) -> None:
    for space in _NAMESPACES:
        for name in _PUBLISHED.get(key, []):
            space.pop(name, None)
    _PUBLISHED.pop(key, None)
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
    for space in _NAMESPACES:
        space.update(named)
    _PUBLISHED[key] = list(named)


on_change(_publish)


FAMILY_ENVS: dict[str, Mapping[str, type]] = {"robust": ROBUST_ENVS, "force": FORCE_ENVS}


__all__ = ["FAMILY_ENVS", "FORCE_ENVS", "PACKAGE", "ROBUST_ENVS", "follow", "paper_class"]
