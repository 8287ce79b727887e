"""rliable's statistics for few runs (Agarwal et al., "Deep Reinforcement Learning at the Edge of
the Statistical Precipice", NeurIPS 2021): performance profiles, and the pairs of a probability
of improvement, with stratified-bootstrap 95 % intervals.

The definitions are rliable's (google-research/rliable, v1.2.0):

- performance profile: the fraction of runs whose score exceeds τ, over all (task, seed) runs
  (``rliable.library.run_score_deviation`` / ``score_distributions``, through
  ``create_performance_profile``);
- IQM: the 25 %-trimmed mean of all runs (``rliable.metrics.aggregate_iqm``), here
  ``rrls.report.stats.aggregate_iqm``;
- probability of improvement: per task P(X > Y) + P(X = Y)/2 over the pairs of runs (the
  Mann-Whitney U / (n·m)), averaged over tasks (``rliable.metrics.probability_of_improvement``),
  here ``rrls.report.stats.aggregate_poi``;
- intervals: percentile bootstrap, runs resampled within each task, tasks kept
  (``rliable.library.StratifiedBootstrap`` with ``task_bootstrap=False``).

Why not ``rliable`` itself: its 1.2.0 requires ``arch`` (which pulls ``statsmodels``),
``seaborn`` and ``absl-py`` for three one-line statistics and a bootstrap that SciPy and NumPy
already give; and it takes a (runs × tasks) matrix, where a benchmark can hold different seed
counts per task. Same definitions, no new dependency.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from rrls.algorithms import normalisers
from rrls.report import stats

__all__ = ["MIN_SEEDS", "N_RESAMPLES", "performance_profile", "poi_pairs", "taus"]

N_RESAMPLES = 2_000  # rliable's default ``reps`` for performance profiles
MIN_SEEDS = 3  # the fewest runs per task a band is drawn from


def taus(per_algo: dict[str, Sequence[np.ndarray]], n: int = 101) -> np.ndarray:
    """The thresholds of a profile: ``n`` points spanning every algorithm's scores."""
    values = np.concatenate([np.concatenate(list(v)) for v in per_algo.values() if len(v)])
    lo, hi = float(values.min()), float(values.max())
    if lo == hi:
        lo, hi = lo - 0.5, hi + 0.5
    return np.linspace(lo, hi, n)


def _profile(per_task: Sequence[np.ndarray], thresholds: np.ndarray) -> np.ndarray:
    runs = np.concatenate(list(per_task))
    return (runs[:, None] > thresholds[None, :]).mean(axis=0)


def performance_profile(
    per_task: Sequence[np.ndarray], thresholds: np.ndarray, rng: np.random.Generator
) -> dict[str, Any]:
    """``{"profile", "low", "high"}`` at ``thresholds``: the fraction of runs scoring above each
    τ and its 95 % stratified-bootstrap band (``None`` when a task has fewer than
    ``MIN_SEEDS`` runs: a bootstrap of one or two values is no confidence interval)."""
    per_task = [np.asarray(x, dtype=float) for x in per_task if len(x)]
    profile = _profile(per_task, thresholds)
    if not per_task or min(len(x) for x in per_task) < MIN_SEEDS:
        return {"profile": profile, "low": None, "high": None}
    draws = np.empty((N_RESAMPLES, len(thresholds)))
    for b in range(N_RESAMPLES):
        resampled = [x[rng.integers(0, len(x), len(x))] for x in per_task]
        draws[b] = _profile(resampled, thresholds)
    low, high = np.percentile(draws, [2.5, 97.5], axis=0)
    return {"profile": profile, "low": low, "high": high}


def poi_pairs(
    per_seed: dict[str, dict[str, np.ndarray]], baselines: Sequence[str] | None = None
) -> list[dict[str, Any]]:
    """P(X > Y) for every algorithm X against each of ``baselines`` Y present (default: the
    normalised score's two anchors, ``rrls.algorithms.normalisers``), over the tasks where both
    have runs (``per_seed[algo][task]``: per-seed scores)."""
    out = []
    for y in normalisers() if baselines is None else baselines:
        if y not in per_seed:
            continue
        for x in per_seed:
            if x == y or any(p["x"] == y and p["y"] == x for p in out):
                continue  # P(Y > X) = 1 - P(X > Y): already shown
            tasks = [t for t in per_seed[x] if len(per_seed[x][t]) and len(per_seed[y].get(t, []))]
            pairs = [(per_seed[x][t], per_seed[y][t]) for t in tasks]
            result = stats.aggregate_poi(pairs, stats.rng_for(x, y, "poi-pair"))
            out.append({"x": x, "y": y, **result})
    return out
