"""The statistics of the report: per-seed scores, IQM, CIs, normalised scores, P(improve).

A cell's interval (the mean over a handful of seeds) is Student's t interval, ``mean ± t(0.975, n -
1) · s / sqrt(n)`` (``s`` with ddof=1): a percentile bootstrap of 3 or 5 values cannot leave their
[min, max] and covers far less than 95 % at those sizes (with 3 seeds it *is* about the range),
where the t interval widens as few seeds demand (t = 4.30 at n = 3, 2.78 at n = 5). It assumes
roughly normal seed means; with bimodal seeds (some learned, some not) no interval from 3-5 values
is trustworthy, and the pages say so. Aggregates over many (task, seed) scores keep rliable's
stratified bootstrap. Bootstrap CIs come from ``scipy.stats.bootstrap`` (percentile method, 2 000
resamples), each with its own generator seeded from the cell's name, so a report is reproducible and
a cell's interval does not change when other cells are added. Aggregates over tasks are
*stratified*: seeds are resampled within each task (scipy resamples each sample of a multi-sample
statistic independently), as rliable does.
"""

from __future__ import annotations

import zlib
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from rrls.evaluation.metrics import normalized_score, run_scores

N_RESAMPLES = 2_000


def rng_for(*names: object, seed: int = 0) -> np.random.Generator:
    """A generator fixed by ``seed`` and the cell's name (stable across reports)."""
    key = zlib.crc32("/".join(map(str, names)).encode())
    return np.random.default_rng([seed, key])


def iqm(x: Sequence[float] | np.ndarray) -> float:
    """Interquartile mean: the mean of the middle 50 % (``scipy.stats.trim_mean(x, 0.25)``)."""
    from scipy.stats import trim_mean

    return float(trim_mean(np.asarray(x, dtype=float), 0.25))


def bootstrap_ci(
    samples: Sequence[np.ndarray],
    statistic: Callable[..., float],
    rng: np.random.Generator,
    confidence: float = 0.95,
) -> list[float] | None:
    """Percentile bootstrap CI of ``statistic(*samples, axis=-1)`` (vectorised: it reduces the
    last axis); each sample resampled on its own (stratified). ``None`` when a sample has fewer
    than two values (no interval exists)."""
    from scipy.stats import bootstrap

    samples = [np.asarray(s, dtype=float) for s in samples]
    if not samples or min(len(s) for s in samples) < 2:
        return None
    if all(np.all(s == s[0]) for s in samples):
        value = float(statistic(*samples, axis=-1))
        return [value, value]
    res = bootstrap(
        tuple(samples),
        statistic,
        n_resamples=N_RESAMPLES,
        confidence_level=confidence,
        method="percentile",
        vectorized=True,
        axis=-1,
        paired=False,
        rng=rng,
    )
    return [float(res.confidence_interval.low), float(res.confidence_interval.high)]


def t_bounds(x: np.ndarray, axis: int = 0, confidence: float = 0.95) -> tuple[Any, Any]:
    """Student's t interval of the mean of ``x`` along ``axis`` (at least two values there):
    ``(low, high)``, vectorised over the other axes (the curves' bands use it per bin)."""
    from scipy.stats import t

    n = x.shape[axis]
    mean = x.mean(axis=axis)
    half = t.ppf((1 + confidence) / 2, n - 1) * x.std(axis=axis, ddof=1) / np.sqrt(n)
    return mean - half, mean + half


def t_interval(x: Sequence[float] | np.ndarray, confidence: float = 0.95) -> list[float] | None:
    """Student's t interval of the mean of ``x`` (``None`` with fewer than two values)."""
    x = np.asarray(x, dtype=float)
    if len(x) < 2:
        return None
    low, high = t_bounds(x, 0, confidence)
    return [float(low), float(high)]


def describe(x: Sequence[float] | np.ndarray, rng: np.random.Generator) -> dict[str, Any]:
    """``{"mean", "std", "iqm", "ci95", "n_seeds"}`` of per-seed values; ``std`` over seeds with
    ddof=0 (numpy's default, which the paper's tables are consistent with), ``ci95`` the t
    interval of the mean (``rng`` unused: kept for the callers' one signature)."""
    x = np.asarray(x, dtype=float)
    if len(x) == 0:
        return {"mean": None, "std": None, "iqm": None, "ci95": None, "n_seeds": 0}
    return {
        "mean": float(x.mean()),
        "std": float(x.std()),
        "iqm": iqm(x),
        "ci95": t_interval(x),
        "n_seeds": len(x),
    }


def per_seed_scores(evaluations: Any) -> Any:
    """One row per (task, algorithm, seed): its worst and average case
    (``rrls.evaluation.metrics.run_scores``, the paper's one definition)."""
    return run_scores(evaluations, ("task", "algorithm", "seed"))


def normalise(v: np.ndarray, v_td3: float, v_m2td3: float) -> np.ndarray:
    """Paper §5: ``(v - v_TD3) / |v_M2TD3 - v_TD3|`` with v_TD3, v_M2TD3 the seed means
    (``rrls.evaluation.metrics.normalized_score``); refused when the span is 0 or not finite."""
    return np.asarray(normalized_score(np.asarray(v, dtype=float), v_td3, v_m2td3), dtype=float)


def improvement_probability(x: np.ndarray, y: np.ndarray) -> Any:
    """P(X > Y) + P(X = Y) / 2 for a random seed of each (the Mann-Whitney U over n·m);
    vectorised over leading axes."""
    x, y = np.asarray(x, dtype=float)[..., :, None], np.asarray(y, dtype=float)[..., None, :]
    return ((x > y).mean(axis=(-2, -1)) + 0.5 * (x == y).mean(axis=(-2, -1)))[()]


def aggregate_poi(
    pairs: list[tuple[np.ndarray, np.ndarray]], rng: np.random.Generator
) -> dict[str, Any]:
    """Probability of improvement averaged over tasks, with a stratified bootstrap CI."""
    if not pairs:
        return {"value": None, "ci95": None, "n_tasks": 0}

    def stat(*samples: np.ndarray, axis: int = -1) -> Any:
        pairs_ = range(0, len(samples), 2)
        per_task = [improvement_probability(samples[i], samples[i + 1]) for i in pairs_]
        return np.mean(per_task, axis=0)

    flat = [s for pair in pairs for s in pair]
    value = float(stat(*flat))
    return {"value": value, "ci95": bootstrap_ci(flat, stat, rng), "n_tasks": len(pairs)}


def aggregate_iqm(per_task: list[np.ndarray], rng: np.random.Generator) -> dict[str, Any]:
    """IQM over every (task, seed) score, stratified bootstrap CI; plus the paper's "Average"
    column (mean over tasks of the per-task means and of the per-task stds)."""
    if not per_task:
        return {"iqm": None, "ci95": None, "mean_over_tasks": None, "std_over_tasks": None}

    def stat(*samples: np.ndarray, axis: int = -1) -> Any:
        from scipy.stats import trim_mean

        return trim_mean(np.concatenate(samples, axis=-1), 0.25, axis=-1)

    return {
        "iqm": float(stat(*per_task)),
        "ci95": bootstrap_ci(per_task, stat, rng),
        "mean_over_tasks": float(np.mean([x.mean() for x in per_task])),
        "std_over_tasks": float(np.mean([x.std() for x in per_task])),
        "n_tasks": len(per_task),
    }
