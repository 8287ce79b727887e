"""Deprecated: ``rrls.experiments`` was split by what each part does.

- :mod:`rrls.benchmark` — running a benchmark (``rrls benchmark``);
- :mod:`rrls.submissions` — a policy trained elsewhere entered into one (``rrls submit``);
- :mod:`rrls.report` — its tables, figures and statistics (``rrls report``).

Every old module path still imports (``rrls.experiments.spec`` is :mod:`rrls.benchmark.grid`,
``rrls.experiments.report`` is :mod:`rrls.report.writer`, …) and warns once, naming the new one;
``from rrls.experiments import submit`` still works and warns the same way.
"""

from __future__ import annotations

import importlib
from typing import Any

from rrls.deprecation import moved_modules, warn_deprecated

#: old module → new module, every one of the package's former modules
MOVED = {
    "rrls.experiments.backends": "rrls.benchmark.backends",
    "rrls.experiments.benchfile": "rrls.benchmark.benchfile",
    "rrls.experiments.caveats": "rrls.report.caveats",
    "rrls.experiments.cells": "rrls.report.cells",
    "rrls.experiments.changes": "rrls.benchmark.changes",
    "rrls.experiments.cpu_estimate": "rrls.benchmark.cpu_estimate",
    "rrls.experiments.crosstask": "rrls.report.crosstask",
    "rrls.experiments.exported": "rrls.report.exported",
    "rrls.experiments.figstyle": "rrls.report.figstyle",
    "rrls.experiments.figures": "rrls.report.figures",
    "rrls.experiments.gpu_estimate": "rrls.benchmark.gpu_estimate",
    "rrls.experiments.latex": "rrls.report.latex",
    "rrls.experiments.names": "rrls.report.names",
    "rrls.experiments.origins": "rrls.report.origins",
    "rrls.experiments.pairwise": "rrls.report.pairwise",
    "rrls.experiments.per_run": "rrls.report.per_run",
    "rrls.experiments.pipeline": "rrls.benchmark.pipeline",
    "rrls.experiments.plots": "rrls.report.plots",
    "rrls.experiments.presets": "rrls.benchmark.presets",
    "rrls.experiments.profiles": "rrls.report.profiles",
    "rrls.experiments.rechecked": "rrls.report.rechecked",
    "rrls.experiments.reference": "rrls.report.reference",
    "rrls.experiments.report": "rrls.report.writer",
    "rrls.experiments.runner": "rrls.benchmark.runner",
    "rrls.experiments.spec": "rrls.benchmark.grid",
    "rrls.experiments.stages": "rrls.benchmark.stages",
    "rrls.experiments.stats": "rrls.report.stats",
    "rrls.experiments.store": "rrls.benchmark.store",
    "rrls.experiments.submission": "rrls.submissions.steps",
    "rrls.experiments.submit_checks": "rrls.submissions.checks",
    "rrls.experiments.submitted": "rrls.submissions.steps",
    "rrls.experiments.summary": "rrls.report.summary",
    "rrls.experiments.tables": "rrls.report.tables",
    "rrls.experiments.withdraw": "rrls.submissions.withdraw",
}

_moved = moved_modules(MOVED)


def __getattr__(name: str) -> Any:
    if name == "submit":
        warn_deprecated("rrls.experiments.submit is deprecated; use rrls.submissions.submit")
        return importlib.import_module("rrls.submissions").submit
    return _moved(name)


__all__: list[str] = []
