"""The report: tables, figures and statistics from a benchmark's results (``rrls report``).

``writer`` (:func:`make_report`: ``summary.json``, ``report.md``, the LaTeX/CSV tables and the
figures) reads the result store only, never the training code. Its parts, in the order the
report uses them:

- ``summary`` — the numbers: cells, aggregates, provenance; ``stats``, ``profiles``,
  ``pairwise``, ``per_run`` and ``rechecked`` — bootstrap and t intervals, IQM, rliable's
  profiles, paired comparisons, per-run rows, re-checked worst cases;
- ``caveats`` — what a cell must warn of; ``names`` — display names;
- ``cells``, ``tables``, ``latex`` and ``origins`` — Markdown, LaTeX, CSV and terminal tables;
- ``figures``, ``plots`` and ``figstyle`` — the figures;
- ``reference`` and ``exported`` — reference results as data files (the shipped ones are
  package data here), read and written; ``crosstask`` — the report across benchmarks.

It reads :mod:`rrls.benchmark`'s files and store; nothing below imports it.
"""

from __future__ import annotations

from rrls.lazy import lazy_exports

_WHERE = {
    **dict.fromkeys(
        ["make_cross_report", "make_report", "paper_results", "write_report"], "writer"
    ),
    **dict.fromkeys(
        ["Reference", "ReferenceError", "check_compatible", "load_reference"], "reference"
    ),
}

__getattr__, __dir__ = lazy_exports(__name__, _WHERE, globals())

__all__ = sorted(_WHERE)
