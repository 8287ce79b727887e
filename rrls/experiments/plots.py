"""Figures of the report: training curves (mean and 95 % bootstrap band over seeds, one panel
per task) and the return over the uncertainty set (one panel per parameter). Needs matplotlib."""

from __future__ import annotations

import warnings
from pathlib import Path
from typing import Any

import numpy as np

from rrls.experiments import stats

BINS = 50


def _pyplot() -> Any:
    from rrls.evaluation.plots import pyplot

    return pyplot()


def _algo_label(algo: str) -> str:
    from rrls.experiments.names import NAMES

    return NAMES.get(algo, algo)


def _color(algo: str) -> str:
    """One colour per algorithm in every figure."""
    from rrls.experiments.names import ORDER

    index = ORDER.index(algo) if algo in ORDER else len(ORDER) + sum(map(ord, algo)) % 5
    return f"C{index}"


def _binned(curves: Any, metric: str, steps: int) -> tuple[np.ndarray, dict[tuple, np.ndarray]]:
    """Per (task, algorithm): an array [seeds, BINS] of the metric averaged within step bins,
    gaps carried forward (an episode can span a bin)."""
    edges = np.linspace(0, steps, BINS + 1)
    centres = (edges[:-1] + edges[1:]) / 2
    out: dict[tuple, np.ndarray] = {}
    data = curves.dropna(subset=[metric])
    for (task, algo), group in data.groupby(["task", "algorithm"], sort=True):
        rows = []
        for _, run in group.groupby("seed", sort=True):
            idx = np.clip(
                np.searchsorted(edges, run["step"].to_numpy(), side="right") - 1, 0, BINS - 1
            )
            sums = np.bincount(idx, run[metric].to_numpy(dtype=float), BINS)
            counts = np.bincount(idx, minlength=BINS)
            row = np.where(counts > 0, sums / np.maximum(counts, 1), np.nan)
            for i in range(1, BINS):  # carry forward
                if np.isnan(row[i]):
                    row[i] = row[i - 1]
            first = np.flatnonzero(~np.isnan(row))
            if len(first):
                row[: first[0]] = np.nan
            rows.append(row)
        out[(task, algo)] = np.array(rows)
    return centres, out


def _band(values: np.ndarray, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """95 % bootstrap band of the mean over seeds, per bin (scipy, vectorised over bins)."""
    from scipy.stats import bootstrap

    lo, hi = np.full(values.shape[1], np.nan), np.full(values.shape[1], np.nan)
    ok = ~np.isnan(values).any(axis=0)
    if values.shape[0] < 2 or not ok.any():
        return lo, hi
    sub = values[:, ok]
    if np.all(sub == sub[0]):
        return np.where(ok, values[0], np.nan), np.where(ok, values[0], np.nan)
    res = bootstrap((sub,), np.mean, axis=0, n_resamples=1_000, method="percentile", rng=rng)
    lo[ok], hi[ok] = res.confidence_interval.low, res.confidence_interval.high
    return lo, hi


def plot_curves(curves: Any, metric: str, steps: int, path: Path, ylabel: str) -> Path | None:
    """One panel per task, one line per algorithm: the seed mean and its 95 % band."""
    if metric not in curves or curves[metric].notna().sum() == 0:
        return None
    plt = _pyplot()
    centres, binned = _binned(curves, metric, steps)
    tasks = list(dict.fromkeys(t for t, _ in binned))
    fig, axes = plt.subplots(1, len(tasks), figsize=(4.2 * len(tasks), 3.4), squeeze=False)
    for ax, task in zip(axes[0], tasks):
        from rrls.experiments.names import sort_algos

        for algo in sort_algos(a for t, a in binned if t == task):
            values = binned[(task, algo)]
            with warnings.catch_warnings():  # bins before a run's first episode are empty
                warnings.simplefilter("ignore", RuntimeWarning)
                mean = np.nanmean(values, axis=0)
            label = f"{_algo_label(algo)} ({len(values)})"
            ax.plot(centres, mean, label=label, color=_color(algo))
            lo, hi = _band(values, stats.rng_for(task, algo, metric, "band"))
            ax.fill_between(centres, lo, hi, color=_color(algo), alpha=0.2, linewidth=0)
        from rrls.experiments.names import task_name

        ax.set_title(task_name(task))
        ax.set_xlabel("environment steps")
        ax.set_ylabel(ylabel)
        ax.legend(fontsize=7, title="algorithm (seeds)", title_fontsize=7)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def plot_over_set(evaluations: Any, task: str, path: Path) -> Path | None:
    """Mean return (over seeds, episodes and the other parameters) along each parameter."""
    data = evaluations[evaluations["task"] == task]
    fixed = {
        "point",
        "episode",
        "episode_seed",
        "return",
        "length",
        "terminated",
        "diverged",
        "algorithm",
        "task",
        "uncertainty",
        "train_set",
        "seed",
        "steps",
    }
    params = [
        c
        for c in data.columns
        if c not in fixed and not c.endswith("_version") and data[c].notna().any()
    ]
    if not params:
        return None
    plt = _pyplot()
    fig, axes = plt.subplots(1, len(params), figsize=(4.2 * len(params), 3.4), squeeze=False)
    from rrls.experiments.names import sort_algos, task_name

    for ax, name in zip(axes[0], params):
        for algo in sort_algos(data["algorithm"].unique()):
            sel = data[data["algorithm"] == algo]
            curve = sel.groupby(name)["return"].mean()
            ax.plot(
                curve.index,
                curve.to_numpy(),
                marker="o",
                ms=3,
                label=_algo_label(algo),
                color=_color(algo),
            )
        ax.set_xlabel(name)
        ax.set_ylabel("mean return" if len(params) == 1 else "mean return (others averaged)")
        ax.legend(fontsize=7)
    fig.suptitle(f"{task_name(task)}: return over the uncertainty set", fontsize=10)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def make_figures(tables: dict[str, Any], summary: dict[str, Any], out: Path) -> list[tuple]:
    """Every figure of the report: ``[(caption, path)]``."""
    curves, ev = tables["curves"], tables["evaluations"]
    steps = int(curves["steps"].max()) if len(curves) and "steps" in curves else 0
    figures = []
    if steps:
        for metric, caption, ylabel in (
            ("episode_return", "Training curves: episode return", "episode return"),
            ("eval_nominal_return", "Periodic evaluation: nominal return", "return (nominal)"),
            ("eval_worst_case", "Periodic evaluation: worst case (coarse mesh)", "worst case"),
        ):
            path = plot_curves(curves, metric, steps, out / f"curves_{metric}.png", ylabel)
            if path is not None:
                figures.append((caption + " (mean and 95% bootstrap CI over seeds)", path))
    for task in summary["tasks"]:
        if len(ev) and (ev["task"] == task).any():
            path = plot_over_set(ev, task, out / f"returns_{task}.png")
            if path is not None:
                figures.append((f"Return over the uncertainty set: {task}", path))
    return figures
