"""The report's aggregate figures in rliable's style (``rrls.report.profiles``): performance
profiles of the normalised scores, the IQM with its 95 % CI, and probabilities of improvement.

Each figure is a PNG with a vector PDF beside it (``figstyle.save``); its caption says what the
bands are, and names the tasks whose normalisation is unstable (§) and the cells from fewer than
3 seeds, whose intervals are not confidence intervals. Every row of the tables is drawn: the
reference's rows (``TD3 (ref. quick)``, from their per-seed values) in a darker shade of their
algorithm's colour, dashed, with open markers, beside the benchmark's own solid ones; every
label of a row from fewer than 3 seeds carries †, as its table cells do. Each data artist's
``gid`` names its row (``results:td3``, ``reference_results:td3``), for checks.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from rrls.algorithms import normalisers
from rrls.evaluation.metrics import SCORES
from rrls.report import profiles, stats
from rrls.report.caveats import FEW, few_seeds
from rrls.report.figstyle import (
    PANEL,
    REFERENCE_LS,
    axis_label,
    colours,
    keep_or_close,
    legend_outside,
    markers,
    pyplot,
    reference_colour,
    save,
)
from rrls.report.names import normaliser_names
from rrls.report.summary import Scores
from rrls.report.tables import Row, cell, label, table_rows

__all__ = ["aggregate_figures", "marked", "row_colour"]

TITLES = {"worst_case": "worst case", "average_case": "average case"}
#: the unit of a normalised score: its two anchors (the algorithm table's), by display name
NORMALISED = ", ".join(f"{v} = {name}" for v, name in enumerate(normaliser_names()))


def marked(summary: dict[str, Any], row: Row) -> str:
    """A row's label in a figure: the table's, with † where a task's cell has fewer than 3
    seeds (the mark its table cells carry), so a figure does not pass two seeds for many."""
    few = any(few_seeds(cell(summary, row, t, "worst_case")) for t in summary["tasks"])
    return row[0] + (FEW if few else "")


def row_colour(row: Row, colour: dict[str, str]) -> str:
    """The benchmark's own row: its algorithm's colour; a reference's: a shade of it."""
    base = colour.get(row[1], "#777777")
    return base if row[2] == "results" else reference_colour(base)


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
                out.setdefault(row, []).append(stats.normalise(x, ref["zero"], ref["one"]))
    return out


def _style(row: Row, colour: dict[str, str], marker: dict[str, str]) -> dict[str, Any]:
    """A row's line: solid in its algorithm's colour; a reference's dashed, in a shade of it,
    with open markers."""
    own, shade = row[2] == "results", row_colour(row, colour)
    return {
        "color": shade,
        "ls": "-" if own else REFERENCE_LS,
        "marker": marker[row[1]],
        "mfc": shade if own else "white",
        "gid": f"{row[2]}:{row[1]}",
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
        notes.append(f"{FEW} fewer than 3 seeds: the intervals are not confidence intervals")
    if unstable:
        notes.append(f"§ unstable normalisation on {', '.join(unstable)}")
    return f" ({'; '.join(notes)})" if notes else ""


def plot_profiles(
    summary: dict[str, Any], scores: Scores, path: Path, keep: dict[str, Any] | None = None
) -> tuple[str, Path] | None:
    """One panel per score: the fraction of runs with a normalised score above τ. The bands are
    light (a reference's hatched, unfilled), as they overlap where runs are few."""
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
            own = row[2] == "results"
            # one artist per row, its markers every few τ: the legend shows line and marker
            ax.plot(grid, prof["profile"], markevery=every, ms=3, label=marked(summary, row),
                    **style)  # fmt: skip
            if prof["low"] is not None:
                band = {"color": style["color"], "alpha": 0.1, "lw": 0} if own else {
                    "facecolor": "none", "edgecolor": style["color"], "hatch": "////",
                    "alpha": 0.35, "lw": 0,
                }  # fmt: skip
                ax.fill_between(grid, prof["low"], prof["high"], gid=style["gid"], **band)
        ax.set_xlabel(axis_label(f"τ, normalised {TITLES[metric]}", NORMALISED))
        ax.set_ylabel(axis_label("runs scoring above τ", "fraction"))
        ax.set_ylim(0, 1.02)
        ax.set_xlim(grid[0], grid[-1])
        ax.axvline(0, color="grey", lw=0.6, ls=":")  # the 0 anchor
        ax.axvline(1, color="grey", lw=0.6, ls=":")  # the 1 anchor's distance
    shown = [ax for ax in axes[0] if ax.get_visible()]
    legend_outside(shown[-1])
    fig.tight_layout()
    save(fig, path)
    keep_or_close(fig, path, keep)
    caption = (
        "Performance profiles: fraction of (task, seed) runs whose normalised score exceeds τ, "
        "with 95% stratified-bootstrap bands (rliable's definition; drawn only where every "
        f"task has {profiles.MIN_SEEDS} seeds or more); reference rows dashed, in a darker "
        "shade, their bands hatched" + _caveats(summary)
    )
    return caption, path


def plot_iqm(
    summary: dict[str, Any], scores: Scores, path: Path, keep: dict[str, Any] | None = None
) -> tuple[str, Path] | None:
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
            c = cells[row].get(metric) or {}
            if c.get("iqm") is None:
                continue
            own, shade, gid = row[2] == "results", row_colour(row, colour), f"{row[2]}:{row[1]}"
            ci = c.get("ci95")
            if ci and own:
                ax.plot(ci, [yi, yi], color=shade, lw=5, alpha=0.45, solid_capstyle="butt",
                        gid=gid)  # fmt: skip
            elif ci:
                ax.plot(ci, [yi, yi], color=shade, lw=2, ls=REFERENCE_LS, gid=gid)
            ax.plot([c["iqm"]], [yi], "|" if own else "d", color=shade, ms=10 if own else 7,
                    mew=2 if own else 1.5, mfc=shade if own else "white", gid=gid)  # fmt: skip
        ax.set_yticks(y, [marked(summary, r) for r in rows])
        ax.set_xlabel(axis_label(f"IQM, normalised {TITLES[metric]}", NORMALISED, wrap=True))
        ax.axvline(0, color="grey", lw=0.6, ls=":")
        ax.axvline(1, color="grey", lw=0.6, ls=":")
    fig.tight_layout()
    save(fig, path)
    keep_or_close(fig, path, keep)
    caption = (
        "Interquartile mean of the normalised scores over all (task, seed) runs, with its 95% "
        "stratified-bootstrap CI (no bar: fewer than two runs per task); reference rows as "
        "open diamonds in a darker shade, their CI dashed" + _caveats(summary)
    )
    return caption, path


def _baselines(summary: dict[str, Any], scores: Scores) -> list[tuple[Row, dict[str, Any]]]:
    """The normalised score's two anchors (``normalisers``) as the Y of P(X > Y): the
    benchmark's runs, else the reference's row (its per-seed values) where the benchmark has
    none; ``[(row, {task: per-seed worst cases})]`` (the 0 anchor as
    ``poi_over_td3_worst_case`` takes it: ``Scores.zero_seeds``)."""
    tasks, out = summary["tasks"], []
    theirs = {r[1]: r for r in table_rows(summary, "raw_worst_case") if r[2] != "results"}
    zero = normalisers()[0]
    for algo in normalisers():
        own = {t: scores.values(t, algo, "worst_case") for t in tasks}
        if any(len(v) for v in own.values()):
            if algo == zero:
                own = {t: scores.zero_seeds(t) for t in tasks}
            out.append(((label(summary, algo), algo, "results"), own))
        elif algo in theirs:
            row = theirs[algo]
            out.append((row, {t: _values(scores, row, t, "worst_case") for t in tasks}))
    return out


def _poi_rows(summary: dict[str, Any], scores: Scores) -> list[dict[str, Any]]:
    """Every algorithm X of the benchmark against each anchor Y: against the 0 anchor the
    numbers of the report's table (``poi_over_td3_worst_case``), against the 1 anchor the same
    statistic."""
    tasks, out = summary["tasks"], []
    zero = normalisers()[0]
    for y_row, y_seeds in _baselines(summary, scores):
        for x in summary["algorithms"]:
            x_row = (label(summary, x), x, "results")
            if x == y_row[1] and y_row[2] == "results":
                continue
            if any(p["x"][1] == y_row[1] and p["y"][1] == x for p in out):
                continue  # P(Y > X) = 1 - P(X > Y): already shown
            if y_row[1] == zero:
                result = (summary["aggregate"].get(x) or {}).get("poi_over_td3_worst_case")
            else:
                pairs = [
                    (scores.values(t, x, "worst_case"), y_seeds[t])
                    for t in tasks
                    if len(scores.values(t, x, "worst_case")) and len(y_seeds[t])
                ]
                result = stats.aggregate_poi(pairs, stats.rng_for(x, y_row[1], "poi-pair"))
            if result and result.get("value") is not None:
                out.append({"x": x_row, "y": y_row, **result})
    return out


def plot_poi(
    summary: dict[str, Any], scores: Scores, path: Path, keep: dict[str, Any] | None = None
) -> tuple[str, Path] | None:
    """P(X > Y) of the worst case for every algorithm X against the normalised score's anchors
    (the reference's where the benchmark has none: a submissions-only report has its table, so its
    figure), with 95 % CIs; a pair against a reference's row dashed, with an open marker."""
    pairs = _poi_rows(summary, scores)
    if not pairs:
        return None
    plt = pyplot()
    colour = colours(summary["algorithms"])
    fig, ax = plt.subplots(figsize=(PANEL[0], max(PANEL[1], 0.25 * len(pairs) + 0.8)))
    y = np.arange(len(pairs))[::-1]
    for yi, pair in zip(y, pairs):
        ours, c = pair["y"][2] == "results", colour[pair["x"][1]]
        gid = f"results:{pair['x'][1]}>{pair['y'][2]}:{pair['y'][1]}"
        if pair.get("ci95"):
            band = {"lw": 5, "alpha": 0.45} if ours else {"lw": 2, "ls": REFERENCE_LS}
            ax.plot(pair["ci95"], [yi, yi], color=c, gid=gid, **band)
        ax.plot([pair["value"]], [yi], "|" if ours else "d", color=c, ms=12 if ours else 7,
                mew=2 if ours else 1.5, mfc=c if ours else "white", gid=gid)  # fmt: skip
    names = [f"{marked(summary, p['x'])} > {marked(summary, p['y'])}" for p in pairs]
    ax.set_yticks(y, names)
    ax.set_xlim(-0.02, 1.02)  # a marker at 0 or 1 whole
    ax.axvline(0.5, color="grey", lw=0.6, ls=":")
    ax.set_xlabel(axis_label("P(X > Y), worst case", "probability"))
    fig.tight_layout()
    save(fig, path)
    keep_or_close(fig, path, keep)
    against = any(p["y"][2] != "results" for p in pairs)
    caption = (
        "Probability of improvement of the worst case: P(X > Y) for a random seed of each, "
        "averaged over tasks, with 95% stratified-bootstrap CIs"
        + ("; Y from the reference's per-seed values: dashed, open diamonds" if against else "")
        + _caveats(summary, normalised=False)
    )
    return caption, path


def aggregate_figures(
    tables: dict[str, Any],
    summary: dict[str, Any],
    out: Path,
    reference: Any = None,
    keep: dict[str, Any] | None = None,
) -> list[tuple[str, Path]]:
    """The rliable-style figures that the summary has data for: ``[(caption, path)]``
    (``keep``: see ``figstyle.keep_or_close``)."""
    scores = Scores(tables, reference, summary["uncertainty"])
    made = [
        plot_profiles(summary, scores, out / "performance_profiles.png", keep),
        plot_iqm(summary, scores, out / "iqm.png", keep),
        plot_poi(summary, scores, out / "probability_of_improvement.png", keep),
    ]
    return [m for m in made if m is not None]
