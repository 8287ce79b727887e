"""The report's aggregate figures in rliable's style (``rrls.experiments.profiles``): performance
profiles of the normalised scores, the IQM with its 95 % CI, and probabilities of improvement.

Each figure is a PNG with a vector PDF beside it (``figstyle.save``); its caption says what the
bands are, and names the tasks whose normalisation is unstable (§) and the cells from fewer than
3 seeds, whose intervals are not confidence intervals. Every row of the tables is drawn: the
reference's rows (``TD3 (ref. quick)``, from their per-seed values) in their algorithm's colour,
dashed, with open markers, beside the benchmark's own solid ones.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from rrls.evaluation.metrics import SCORES
from rrls.experiments import profiles, stats
from rrls.experiments.figstyle import PANEL, colours, markers, pyplot, save
from rrls.experiments.names import display_name
from rrls.experiments.summary import Scores
from rrls.experiments.tables import Row, table_rows

__all__ = ["aggregate_figures"]

TITLES = {"worst_case": "worst case", "average_case": "average case"}


def _values(scores: Scores, row: Row, task: str, metric: str) -> np.ndarray:
    """A table row's per-seed ``metric`` on ``task``: the benchmark's runs, or the reference's
    per-seed values (empty where it has none)."""
    if row[2] == "results":
        return scores.values(task, row[1], metric)
    ref = scores.reference_row(task, row[1], metric) or {}
    return np.asarray(ref.get("values") or [], dtype=float)


def _normalised(scores: Scores, tasks: list[str], rows: list[Row], metric: str) -> dict:
    """``{row: [per-seed normalised scores of each task]}`` (tasks with a normaliser)."""
    out: dict[Row, list[np.ndarray]] = {}
    for row in rows:
        for task in tasks:
            ref, x = scores.norm_refs(task, metric), _values(scores, row, task, metric)
            if ref is not None and len(x):
                out.setdefault(row, []).append(stats.normalise(x, ref["td3"], ref["m2td3"]))
    return out


def _style(row: Row, colour: dict[str, str], marker: dict[str, str]) -> dict[str, Any]:
    """A row's line: its algorithm's colour; a reference's dashed with open markers."""
    own = row[2] == "results"
    return {
        "color": colour[row[1]],
        "ls": "-" if own else "--",
        "marker": marker[row[1]],
        "mfc": colour[row[1]] if own else "white",
    }


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
    rows = table_rows(summary, "raw_worst_case")
    data = {m: _normalised(scores, summary["tasks"], rows, m) for m in SCORES}
    if not any(data.values()):
        return None
    plt = pyplot()
    algos = [r[1] for r in rows]
    colour, marker = colours(algos), markers(algos)
    fig, axes = plt.subplots(1, 2, figsize=(2 * PANEL[0], PANEL[1]), squeeze=False)
    for ax, metric in zip(axes[0], SCORES):
        per_row = data[metric]
        if not per_row:
            ax.set_visible(False)
            continue
        grid = profiles.taus(per_row)
        every = max(1, len(grid) // 6)
        for row in [r for r in rows if r in per_row]:
            rng = stats.rng_for(row[1], row[2], metric, "profile")
            prof = profiles.performance_profile(per_row[row], grid, rng)
            style = _style(row, colour, marker)
            ax.plot(grid, prof["profile"], color=style["color"], ls=style["ls"], label=row[0])
            ax.plot(
                grid[::every],
                prof["profile"][::every],
                ls="none",
                ms=3,
                **{k: v for k, v in style.items() if k != "ls"},
            )
            if prof["low"] is not None:
                ax.fill_between(grid, prof["low"], prof["high"], color=style["color"], alpha=0.15)
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
        f"task has {profiles.MIN_SEEDS} seeds or more); reference rows dashed" + _caveats(summary)
    )
    return caption, path


def plot_iqm(summary: dict[str, Any], scores: Scores, path: Path) -> tuple[str, Path] | None:
    """Per score, the IQM of the normalised scores of each row (the benchmark's algorithms and
    the reference's) and its 95 % CI."""
    rows = table_rows(summary, "raw_worst_case")
    # the benchmark's own rows: the summary's aggregates (the numbers summary.json states); the
    # reference's: the same statistic over its per-seed values
    agg = summary["aggregate"]
    cells: dict[Row, dict[str, dict[str, Any]]] = {
        r: {m: (agg.get(r[1]) or {}).get(f"normalised_{m}") or {} for m in SCORES}
        for r in rows
        if r[2] == "results"
    }
    theirs = [r for r in rows if r[2] != "results"]
    for metric in SCORES:
        for row, per_task in _normalised(scores, summary["tasks"], theirs, metric).items():
            rng = stats.rng_for(row[1], row[2], metric, "iqm")
            cells.setdefault(row, {})[metric] = stats.aggregate_iqm(per_task, rng)
    rows = [r for r in rows if (cells.get(r, {}).get("worst_case") or {}).get("iqm") is not None]
    if not rows:
        return None
    plt = pyplot()
    colour = colours([r[1] for r in rows])
    height = max(PANEL[1], 0.3 * len(rows) + 0.8)
    fig, axes = plt.subplots(1, 2, figsize=(2 * PANEL[0], height), squeeze=False, sharey=True)
    y = np.arange(len(rows))[::-1]
    for ax, metric in zip(axes[0], SCORES):
        for yi, row in zip(y, rows):
            cell = cells[row].get(metric) or {}
            if cell.get("iqm") is None:
                continue
            own = row[2] == "results"
            ci = cell.get("ci95")
            if ci:
                ax.plot(
                    ci, [yi, yi], color=colour[row[1]], lw=5, alpha=0.45 if own else 0.2,
                    solid_capstyle="butt",
                )  # fmt: skip
            ax.plot([cell["iqm"]], [yi], "|" if own else "d", color=colour[row[1]], ms=10,
                    mew=2, mfc=colour[row[1]] if own else "white")  # fmt: skip
        ax.set_yticks(y, [r[0] for r in rows])
        ax.set_xlabel(f"IQM normalised {TITLES[metric]}")
        ax.axvline(0, color="grey", lw=0.6, ls=":")
        ax.axvline(1, color="grey", lw=0.6, ls=":")
    fig.tight_layout()
    save(fig, path)
    plt.close(fig)
    caption = (
        "Interquartile mean of the normalised scores over all (task, seed) runs, with its 95% "
        "stratified-bootstrap CI (no bar: fewer than two runs per task); reference rows as "
        "open diamonds" + _caveats(summary)
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
    names = [f"{display_name(p['x'])} > {display_name(p['y'])}" for p in pairs]
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
        plot_iqm(summary, scores, out / "iqm.png"),
        plot_poi(summary, scores, out / "probability_of_improvement.png"),
    ]
    return [m for m in made if m is not None]
