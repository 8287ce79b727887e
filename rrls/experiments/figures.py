"""The report's aggregate figures in rliable's style (``rrls.experiments.profiles``): performance
profiles of the normalised scores, the IQM with its 95 % CI, and probabilities of improvement.

Each figure is a PNG with a vector PDF beside it (``figstyle.save``); its caption says what the
bands are, and names the tasks whose normalisation is unstable (§) and the cells from fewer than
3 seeds, whose intervals are not confidence intervals.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from rrls.evaluation.metrics import SCORES
from rrls.experiments import profiles, stats
from rrls.experiments.figstyle import PANEL, colours, markers, pyplot, save
from rrls.experiments.names import NAMES, sort_algos
from rrls.experiments.summary import Scores

__all__ = ["aggregate_figures"]

TITLES = {"worst_case": "worst case", "average_case": "average case"}


def _normalised(scores: Scores, tasks: list[str], algos: list[str], metric: str) -> dict:
    """``{algo: [per-seed normalised scores of each task]}`` (tasks with a normaliser)."""
    out: dict[str, list[np.ndarray]] = {}
    for algo in algos:
        for task in tasks:
            ref, x = scores.norm_refs(task, metric), scores.values(task, algo, metric)
            if ref is not None and len(x):
                out.setdefault(algo, []).append(stats.normalise(x, ref["td3"], ref["m2td3"]))
    return out


def _caveats(summary: dict[str, Any], normalised: bool = True) -> str:
    """What a figure's caption must warn of: intervals from fewer than 3 seeds, and (for the
    normalised scores) the tasks whose normalisation is unstable."""
    unstable = sorted({u["task"] for u in summary.get("unstable") or []} if normalised else [])
    seeds = [
        c["worst_case"]["n_seeds"]
        for by in summary["results"].values()
        for c in by.values()
        if c["worst_case"]["n_seeds"]
    ]
    notes = []
    if seeds and min(seeds) < 3:
        notes.append("fewer than 3 seeds: the intervals are not confidence intervals")
    if unstable:
        notes.append(f"§ unstable normalisation on {', '.join(unstable)}")
    return f" ({'; '.join(notes)})" if notes else ""


def plot_profiles(summary: dict[str, Any], scores: Scores, path: Path) -> tuple[str, Path] | None:
    """One panel per score: the fraction of runs with a normalised score above τ."""
    algos = summary["algorithms"]
    data = {m: _normalised(scores, summary["tasks"], algos, m) for m in SCORES}
    if not any(data.values()):
        return None
    plt = pyplot()
    colour, marker = colours(algos), markers(algos)
    fig, axes = plt.subplots(1, 2, figsize=(2 * PANEL[0], PANEL[1]), squeeze=False)
    for ax, metric in zip(axes[0], SCORES):
        per_algo = data[metric]
        if not per_algo:
            ax.set_visible(False)
            continue
        grid = profiles.taus(per_algo)
        for algo in sort_algos(per_algo):
            rng = stats.rng_for(algo, metric, "profile")
            prof = profiles.performance_profile(per_algo[algo], grid, rng)
            ax.plot(grid, prof["profile"], color=colour[algo], label=NAMES.get(algo, algo))
            ax.plot(
                grid[:: len(grid) // 6],
                prof["profile"][:: len(grid) // 6],
                ls="none",
                marker=marker[algo],
                ms=3,
                color=colour[algo],
            )
            if prof["low"] is not None:
                ax.fill_between(grid, prof["low"], prof["high"], color=colour[algo], alpha=0.2)
        ax.set_xlabel(f"normalised {TITLES[metric]} τ")
        ax.set_ylabel("fraction of runs > τ")
        ax.set_ylim(0, 1.02)
        ax.set_xlim(grid[0], grid[-1])
        ax.axvline(0, color="grey", lw=0.6, ls=":")  # TD3
        ax.axvline(1, color="grey", lw=0.6, ls=":")  # M2TD3's distance
    axes[0][0].legend(frameon=False)
    fig.tight_layout()
    save(fig, path)
    plt.close(fig)
    caption = (
        "Performance profiles: fraction of (task, seed) runs whose normalised score exceeds τ, "
        "with 95% stratified-bootstrap bands (rliable's definition; drawn only where every "
        f"task has {profiles.MIN_SEEDS} seeds or more)" + _caveats(summary)
    )
    return caption, path


def plot_iqm(summary: dict[str, Any], path: Path) -> tuple[str, Path] | None:
    """Per score, the IQM of the normalised scores of each algorithm and its 95 % CI."""
    agg = summary["aggregate"]
    algos = [a for a in summary["algorithms"] if (agg.get(a) or {}).get("normalised_worst_case")]
    algos = [a for a in algos if agg[a]["normalised_worst_case"].get("iqm") is not None]
    if not algos:
        return None
    plt = pyplot()
    colour = colours(summary["algorithms"])
    height = max(PANEL[1], 0.3 * len(algos) + 0.8)
    fig, axes = plt.subplots(1, 2, figsize=(2 * PANEL[0], height), squeeze=False, sharey=True)
    y = np.arange(len(algos))[::-1]
    for ax, metric in zip(axes[0], SCORES):
        for yi, algo in zip(y, algos):
            cell = agg[algo][f"normalised_{metric}"]
            if cell.get("iqm") is None:
                continue
            ci = cell.get("ci95")
            if ci:
                ax.plot(ci, [yi, yi], color=colour[algo], lw=5, alpha=0.45, solid_capstyle="butt")
            ax.plot([cell["iqm"]], [yi], "|", color=colour[algo], ms=12, mew=2)
        ax.set_yticks(y, [NAMES.get(a, a) for a in algos])
        ax.set_xlabel(f"IQM normalised {TITLES[metric]}")
        ax.axvline(0, color="grey", lw=0.6, ls=":")
        ax.axvline(1, color="grey", lw=0.6, ls=":")
    fig.tight_layout()
    save(fig, path)
    plt.close(fig)
    caption = (
        "Interquartile mean of the normalised scores over all (task, seed) runs, with its 95% "
        "stratified-bootstrap CI (no bar: fewer than two runs per task)" + _caveats(summary)
    )
    return caption, path


def plot_poi(summary: dict[str, Any], scores: Scores, path: Path) -> tuple[str, Path] | None:
    """P(X > Y) of the worst case for every algorithm X against TD3 and M2TD3, with 95 % CIs."""
    tasks, algos = summary["tasks"], summary["algorithms"]
    per_seed = {a: {t: scores.values(t, a, "worst_case") for t in tasks} for a in algos}
    for task in tasks:  # TD3 from the reference where the benchmark has none
        if "td3" in per_seed and not len(per_seed["td3"][task]):
            per_seed["td3"][task] = scores.td3_seeds(task)
    pairs = [p for p in profiles.poi_pairs(per_seed) if p["value"] is not None]
    if not pairs:
        return None
    plt = pyplot()
    colour = colours(algos)
    fig, ax = plt.subplots(figsize=(PANEL[0], max(PANEL[1], 0.25 * len(pairs) + 0.8)))
    y = np.arange(len(pairs))[::-1]
    for yi, pair in zip(y, pairs):
        if pair["ci95"]:
            ax.plot(pair["ci95"], [yi, yi], color=colour[pair["x"]], lw=5, alpha=0.45)
        ax.plot([pair["value"]], [yi], "|", color=colour[pair["x"]], ms=12, mew=2)
    names = [f"{NAMES.get(p['x'], p['x'])} > {NAMES.get(p['y'], p['y'])}" for p in pairs]
    ax.set_yticks(y, names)
    ax.set_xlim(0, 1)
    ax.axvline(0.5, color="grey", lw=0.6, ls=":")
    ax.set_xlabel("P(X > Y), worst case")
    fig.tight_layout()
    save(fig, path)
    plt.close(fig)
    caption = (
        "Probability of improvement of the worst case: P(X > Y) for a random seed of each, "
        "averaged over tasks, with 95% stratified-bootstrap CIs"
        + _caveats(summary, normalised=False)
    )
    return caption, path


def aggregate_figures(
    tables: dict[str, Any], summary: dict[str, Any], out: Path, reference: Any = None
) -> list[tuple[str, Path]]:
    """The rliable-style figures that the summary has data for: ``[(caption, path)]``."""
    scores = Scores(tables, reference, summary["uncertainty"])
    made = [
        plot_profiles(summary, scores, out / "performance_profiles.png"),
        plot_iqm(summary, out / "iqm.png"),
        plot_poi(summary, scores, out / "probability_of_improvement.png"),
    ]
    return [m for m in made if m is not None]
