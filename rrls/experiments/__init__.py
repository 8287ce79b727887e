"""Experiments: the paper's comparison from one command (``rrls benchmark``, ``rrls report``).

``spec`` (what a benchmark is, presets), ``pipeline`` (what a group of runs does: train,
evaluate, play the adversary), ``backends`` (where: a local process pool or Ray),
``runner`` (the driver: resume, progress), ``store`` (tidy result tables), ``report`` (statistics,
tables, figures; reads the store only, never the training code), ``submission`` (a policy
trained elsewhere evaluated under a benchmark's protocol: ``submit``), ``reference`` (reference
results as data files).
"""

from rrls.experiments.submission import submit

__all__ = ["submit"]
