"""Running a benchmark: the paper's comparison from one command (``rrls benchmark``).

Read in the order a benchmark runs:

- ``grid`` — what a benchmark is (:class:`Benchmark`: a grid of runs, algorithm × task × seed,
  under one evaluation ``Protocol``), ``presets`` (``paper``, ``quick``, ``smoke``, …) and
  ``validation`` (everything that would keep it from running, refused before it starts);
- ``benchfile`` — ``benchmark.json``, the benchmark's file (written once, checked on resume);
- ``pipeline`` — what a group of runs does: train, evaluate, play the adversary (``stages``:
  the evaluations, which ``rrls submit`` runs too);
- ``backends`` — where the groups run: a local process pool or Ray; ``runner`` — the driver:
  resume, progress, Ctrl-C (:func:`benchmark`);
- ``store`` — the tidy result tables every report reads, and ``changes`` — their
  all-or-nothing updates;
- ``cpu_estimate`` / ``gpu_estimate`` — the wall-time estimates of ``--dry-run``.

The report is the layer above (:mod:`rrls.report`), submissions beside it
(:mod:`rrls.submissions`); nothing here imports either.
"""

from __future__ import annotations

from rrls.lazy import lazy_exports

_WHERE = {
    **dict.fromkeys(
        ["Benchmark", "PRESETS", "RunKey", "SpecError", "make_spec", "read_protocol"], "grid"
    ),
    **dict.fromkeys(["benchmark", "kept_runs", "pending_runs"], "runner"),
    "build_store": "store",
    "estimate": "cpu_estimate",
}

__getattr__, __dir__ = lazy_exports(__name__, _WHERE, globals())

__all__ = sorted(_WHERE)
