"""The original RRLS module ``rrls.evaluate``: ``generate_evaluation_set`` and its constants.

The original built all ``EVALUATION_ROBUST_*`` lists (5 660 environments) at import. Here each
constant is a lazy :class:`~rrls.evaluation.EvaluationSet` made on first access of its name
(module ``__getattr__``), and its environments are built only when read. The Hopper sets act on
``RobustHopper`` (the original built them from ``RobustWalker2d``, docs/differences.md #8).

>>> from rrls.evaluate import EVALUATION_ROBUST_HOPPER_2D
>>> len(EVALUATION_ROBUST_HOPPER_2D)
100
"""

from __future__ import annotations

from rrls.evaluation.mesh import EvaluationSet, generate_evaluation_set

#: constant suffix -> (task key, set name), as named by the original code
_CONSTANTS = {
    f"EVALUATION_ROBUST_{stem}_{dim}D": (task, f"{dim}d")
    for stem, task, dims in (
        ("ANT", "ant", (1, 2, 3)),
        ("HUMANOID_STANDUP", "humanoidstandup", (1, 2, 3)),
        ("WALKER", "walker", (1, 2, 3)),
        ("HALF_CHEETAH", "halfcheetah", (1, 2, 3)),
        ("INVERTED_PENDULUM", "invertedpendulum", (1, 2)),
        ("HOPPER", "hopper", (1, 2, 3)),
    )
    for dim in dims
}


def __getattr__(name: str) -> EvaluationSet:
    if name not in _CONSTANTS:
        raise AttributeError(f"module 'rrls.evaluate' has no attribute {name!r}")
    from rrls.envs import FAMILY_ENVS
    from rrls.tasks import TASKS

    task, set_name = _CONSTANTS[name]
    spec = TASKS[task]  # the table's bounds and family: no env is built to make the set
    env_class = FAMILY_ENVS[spec.families[set_name]][task]
    value = generate_evaluation_set(env_class, spec.sets[set_name], nb_mesh_dim=10)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted([*globals(), *_CONSTANTS])


__all__ = ["generate_evaluation_set", *_CONSTANTS]  # noqa: PLE0604
