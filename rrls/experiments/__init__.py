"""Experiments: the paper's comparison from one command (``rrls benchmark``, ``rrls report``).

``spec`` (what a benchmark is, presets), ``pipeline`` (what a group of runs does: train,
evaluate, play the adversary), ``backends`` (where: a local process pool or Ray),
``runner`` (the driver: resume, progress), ``store`` (tidy result tables), ``report``
(report.md; reads the store only, never the training code) with ``summary`` (the numbers:
cells, aggregates, provenance), ``stats`` and ``profiles`` (bootstrap CIs, IQM, rliable's
profiles and pairs), ``caveats`` (what a cell must warn of), ``cells`` and ``tables`` (LaTeX,
CSV, markdown, terminal), ``plots``, ``figures`` and ``figstyle`` (figures), ``submission``
(a policy trained elsewhere evaluated under a benchmark's protocol: ``submit``), ``reference``
(reference results as data files).
"""

from rrls.experiments.submission import submit

__all__ = ["submit"]
