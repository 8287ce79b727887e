"""``rrls.evaluate``: the original RRLS module path, kept for its names (deprecated).

Evaluate a policy with :func:`rrls.evaluation.evaluate` (also ``rrls.evaluate.evaluate``).
Calling the module itself, ``rrls.evaluate(policy, "hopper")``, still works but is deprecated
(a ``DeprecationWarning``): a module made callable is machinery nobody reading the code expects,
and the original path must stay a module for the names below.

The original module's ``EVALUATION_ROBUST_*`` constants still import, with a
``DeprecationWarning`` (use :func:`rrls.evaluation.default_evaluation_set`). The original built
all of them (5 660 environments) at import; here each is a lazy
:class:`~rrls.evaluation.EvaluationSet` made on first access of its name (module
``__getattr__``; not listed by ``dir()``, like any deprecated name), and its environments are
built only when read. The Hopper sets act on
``RobustHopper`` (the original built them from ``RobustWalker2d``, docs/differences.md #8).

>>> import warnings
>>> with warnings.catch_warnings():
...     warnings.simplefilter("ignore", DeprecationWarning)
...     from rrls.evaluate import EVALUATION_ROBUST_HOPPER_2D
>>> len(EVALUATION_ROBUST_HOPPER_2D)
100
"""

from __future__ import annotations

import sys
import types
from typing import Any

from rrls.deprecation import warn_deprecated
from rrls.evaluation.mesh import EvaluationSet, generate_evaluation_set
from rrls.evaluation.result import EvaluationResult
from rrls.evaluation.static import evaluate

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
#: the constants built so far (kept out of the module's namespace, so each access warns)
_BUILT: dict[str, EvaluationSet] = {}


def __getattr__(name: str) -> EvaluationSet:
    if name not in _CONSTANTS:
        raise AttributeError(f"module 'rrls.evaluate' has no attribute {name!r}")
    task, set_name = _CONSTANTS[name]
    warn_deprecated(
        f"rrls.evaluate.{name} is deprecated; use "
        f'rrls.evaluation.default_evaluation_set("{task}", "{set_name}")'
    )
    if name not in _BUILT:
        from rrls.envs import FAMILY_ENVS
        from rrls.tasks import TASKS

        spec = TASKS[task]  # the table's bounds and family: no env is built to make the set
        env_class = FAMILY_ENVS[spec.families[set_name]][task]
        _BUILT[name] = generate_evaluation_set(env_class, spec.sets[set_name], mesh=10)
    return _BUILT[name]


class _CallableModule(types.ModuleType):
    """The module, callable as :func:`rrls.evaluation.evaluate` (deprecated: call that)."""

    def __call__(self, *args: Any, **kwargs: Any) -> EvaluationResult:
        warn_deprecated(
            "calling the module rrls.evaluate is deprecated; use rrls.evaluation.evaluate "
            "(the same function)"
        )
        return evaluate(*args, **kwargs)


sys.modules[__name__].__class__ = _CallableModule
#: what ``inspect.signature(rrls.evaluate)`` and IDEs show: the function's signature
__wrapped__ = evaluate

__all__ = ["evaluate", "generate_evaluation_set", *_CONSTANTS]
