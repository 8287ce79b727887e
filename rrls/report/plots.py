"""Figures of the report: training curves (one panel per task: the seed mean with its 95 %
Student-t band from 3 seeds on, else each seed as a thin line) and the return over the uncertainty
set (one panel per parameter, the axis bounded by the set's box); the rliable-style aggregates
come from ``rrls.report.figures``. Style, palette, units and the PDF beside each PNG:
``rrls.report.figstyle``. Needs matplotlib.

Every axis carries its unit (a parameter's from its field: kg, N, a friction coefficient
unitless), the legend sits framed beside the axes, and ``titles=False`` leaves out the titles
a paper's caption replaces (a panel's name stays where it tells panels apart)."""

from __future__ import annotations

import warnings
from pathlib import Path
from typing import Any

import numpy as np

from rrls.evaluation.result_plot import cell_edges, outline_box
from rrls.report import stats
from rrls.report.figstyle import (
    PANEL,
    RC,
    REFERENCE_LS,
    RETURN,
    STEPS,
    axis_label,
    colours,
    keep_or_close,
    legend_outside,
    param_unit,
    pyplot,
    reference_colour,
    save,
)
from rrls.report.figures import aggregate_figures, marked
from rrls.report.names import display_name, sort_algos, task_name

BINS = 50
#: the fewest seeds a shaded band is drawn from (fewer: the seeds as thin lines)
MIN_BAND_SEEDS = 3


def _algo_label(algo: str, names: dict[str, str] | None = None) -> str:
    """An algorithm's name in a figure: the report's (``--rename``, submitted marks) if given."""
    return (names or {}).get(algo) or display_name(algo)


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
    """95 % Student-t band of the mean over seeds, per bin (``stats.t_bounds``; ``rng``
    unused)."""
    lo, hi = np.full(values.shape[1], np.nan), np.full(values.shape[1], np.nan)
    ok = ~np.isnan(values).any(axis=0)
    if values.shape[0] < 2 or not ok.any():
        return lo, hi
    lo[ok], hi[ok] = stats.t_bounds(values[:, ok], axis=0)
    return lo, hi


def plot_curves(
    curves: Any,
    metric: str,
    steps: int,
    path: Path,
    ylabel: str,
    colour: dict[str, str],
    names: dict[str, str] | None = None,
    titles: bool = True,
    keep: dict[str, Any] | None = None,
) -> Path | None:
    """One panel per task, one line per algorithm: the seed mean and its 95 % band (from
    ``MIN_BAND_SEEDS`` seeds; fewer: each seed as a thin line, as a band from two seeds would
    claim a confidence it does not have). ``ylabel``: what the return is (its unit added)."""
    if metric not in curves or curves[metric].notna().sum() == 0:
        return None
    plt = pyplot()
    centres, binned = _binned(curves, metric, steps)
    tasks = list(dict.fromkeys(t for t, _ in binned))
    fig, axes = plt.subplots(
        1, len(tasks), figsize=(PANEL[0] * len(tasks), PANEL[1] + 0.4), squeeze=False
    )
    for ax, task in zip(axes[0], tasks):
        for algo in sort_algos(a for t, a in binned if t == task):
            values = binned[(task, algo)]
            with warnings.catch_warnings():  # bins before a run's first episode are empty
                warnings.simplefilter("ignore", RuntimeWarning)
                mean = np.nanmean(values, axis=0)
            label, gid = f"{_algo_label(algo, names)} ({len(values)})", f"results:{algo}"
            ax.plot(centres, mean, label=label, color=colour[algo], gid=gid)
            if len(values) >= MIN_BAND_SEEDS:
                lo, hi = _band(values, stats.rng_for(task, algo, metric, "band"))
                ax.fill_between(
                    centres, lo, hi, color=colour[algo], alpha=0.2, linewidth=0, gid=gid
                )
            else:
                for run in values:
                    ax.plot(centres, run, color=colour[algo], lw=0.5, alpha=0.6, gid=gid)
        if titles or len(tasks) > 1:  # several panels: the task names them
            ax.set_title(task_name(task))
        ax.set_xlabel(axis_label("training", STEPS))
        ax.set_ylabel(axis_label(ylabel, RETURN))
    legend_outside(axes[0][-1], title="algorithm (seeds)")
    fig.tight_layout()
    save(fig, path)
    keep_or_close(fig, path, keep)
    return path


def set_bounds(task: str, uncertainty: str | None, data: Any, name: str) -> tuple[float, float]:
    """The set's range of parameter ``name`` (``get_uncertainty_set``), else the data's."""
    try:
        from rrls.envs import get_uncertainty_set

        box = get_uncertainty_set(task, str(uncertainty))
        i = list(box.names).index(name)
        return float(box.low[i]), float(box.high[i])
    except (KeyError, ValueError, TypeError):  # a registered set of another name
        return float(data[name].min()), float(data[name].max())


#: the evaluation table's columns that are not a parameter of the set
NOT_PARAMETERS = {
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
    "in_distribution",
}


def set_parameters(data: Any) -> list[str]:
    """The parameters of the set in an evaluation table (its other columns are bookkeeping)."""
    return [
        c
        for c in data.columns
        if c not in NOT_PARAMETERS and not c.endswith("_version") and data[c].notna().any()
    ]


def plot_heatmaps(
    evaluations: Any,
    task: str,
    path: Path,
    uncertainty: str | None,
    names: dict[str, str] | None = None,
    titles: bool = True,
    keep: dict[str, Any] | None = None,
) -> Path | None:
    """For a 2-D set: one panel per algorithm (named above it), the mean return (over seeds
    and episodes) at each mesh point on a shared colour scale (viridis), the worst point
    marked, the axes the set's box."""
    data = evaluations[evaluations["task"] == task]
    params = set_parameters(data)
    if len(params) != 2:
        return None
    a, b = params
    algos = sort_algos(data["algorithm"].unique())
    grids = {
        algo: data[data["algorithm"] == algo].pivot_table(index=b, columns=a, values="return")
        for algo in algos
    }
    values = np.concatenate([g.to_numpy().ravel() for g in grids.values()])
    vmin, vmax = float(np.nanmin(values)), float(np.nanmax(values))
    (xlo, xhi), (ylo, yhi) = (set_bounds(task, uncertainty, data, p) for p in (a, b))
    plt = pyplot()
    fig, axes = plt.subplots(
        1,
        len(algos),
        figsize=(2.3 * len(algos) + 0.8, PANEL[1] + 0.3),
        squeeze=False,
        sharey=True,
        layout="constrained",
    )
    mesh = None
    for ax, algo in zip(axes[0], algos):
        grid = grids[algo]
        xs, ys = grid.columns.to_numpy(dtype=float), grid.index.to_numpy(dtype=float)
        xe, ye = cell_edges(xs), cell_edges(ys)
        mesh = ax.pcolormesh(
            xe,
            ye,
            grid.to_numpy(),
            shading="flat",
            cmap="viridis",
            vmin=vmin,
            vmax=vmax,
        )
        iy, ix = np.unravel_index(np.nanargmin(grid.to_numpy()), grid.shape)
        outline_box(ax, {a: xlo, b: ylo}, {a: xhi, b: yhi}, a, b)
        ax.scatter([xs[ix]], [ys[iy]], marker="x", color="#D55E00", s=30, zorder=3)
        ax.set_xlim(min(xlo, xe[0]), max(xhi, xe[-1]))
        ax.set_ylim(min(ylo, ye[0]), max(yhi, ye[-1]))
        ax.set_title(_algo_label(algo, names))
        ax.set_xlabel(axis_label(a, param_unit(task, a)))
    axes[0][0].set_ylabel(axis_label(b, param_unit(task, b)))
    fig.colorbar(mesh, ax=list(axes[0]), label=axis_label("mean return", RETURN))
    if titles:
        fig.suptitle(
            f"{task_name(task) or task}: mean return over the set (x: worst point; dashed: the "
            "set's bounds)"
        )
    save(fig, path)
    keep_or_close(fig, path, keep)
    return path


def plot_over_set(
    evaluations: Any,
    task: str,
    path: Path,
    colour: dict[str, str],
    uncertainty: str | None,
    names: dict[str, str] | None = None,
    reference: list[tuple[str, str, float]] | None = None,
    titles: bool = True,
    keep: dict[str, Any] | None = None,
) -> Path | None:
    """Mean return (over seeds, episodes and the other parameters) along each parameter, the
    axis bounded by the set's box. ``reference``: ``(label, algorithm, average case)`` of the
    reference's rows on this task, drawn as dashed horizontal lines (a reference file holds no
    per-point returns: its average over the set is what these curves average to)."""
    data = evaluations[evaluations["task"] == task]
    params = set_parameters(data)
    if not params:
        return None
    plt = pyplot()
    fig, axes = plt.subplots(
        1, len(params), figsize=(PANEL[0] * len(params), PANEL[1] + 0.4), squeeze=False
    )
    for ax, name in zip(axes[0], params):
        for algo in sort_algos(data["algorithm"].unique()):
            sel = data[data["algorithm"] == algo]
            curve = sel.groupby(name)["return"].mean()
            ax.plot(
                curve.index,
                curve.to_numpy(),
                marker="o",
                ms=3,
                label=_algo_label(algo, names),
                color=colour[algo],
                gid=f"results:{algo}",
            )
        for text, algo, value in reference or []:
            shade = reference_colour(colour.get(algo, "#777777"))
            ax.axhline(value, color=shade, ls=REFERENCE_LS, lw=1.2, label=text,
                       gid=f"reference_results:{algo}")  # fmt: skip
        ax.set_xlim(*set_bounds(task, uncertainty, data, name))
        ax.set_xlabel(axis_label(name, param_unit(task, name)))
        what = "mean return" + ("" if len(params) == 1 else ", others averaged")
        ax.set_ylabel(axis_label(what, RETURN))
    legend_outside(axes[0][-1])
    if titles:
        fig.suptitle(f"{task_name(task) or task}: return over the uncertainty set")
    fig.tight_layout()
    save(fig, path)
    keep_or_close(fig, path, keep)
    return path


def make_figures(
    tables: dict[str, Any],
    summary: dict[str, Any],
    out: Path,
    reference: Any = None,
    titles: bool = True,
    keep: dict[str, Any] | None = None,
) -> list[tuple]:
    """Every figure of the report: ``[(caption, path)]`` (each PNG with a PDF beside it).
    ``titles=False``: no figure title (the paper's caption says it; ``rrls report
    --no-titles``). ``keep``: a dict that receives each figure by file name, left open for the
    caller to inspect (and close); without it each is closed once saved."""
    from rrls.report.tables import cell, label, table_rows

    curves, ev = tables["curves"], tables["evaluations"]
    steps = int(curves["steps"].max()) if len(curves) and "steps" in curves else 0
    present = [*summary["algorithms"], *(ev["algorithm"].unique() if len(ev) else [])]
    theirs = [r for r in table_rows(summary, "raw_average_case") if r[2] != "results"]
    colour = colours([*present, *(r[1] for r in theirs)])
    names = {a: marked(summary, (label(summary, a), a, "results")) for a in present}
    figures = []
    with pyplot().rc_context(RC):
        if steps:
            for metric, caption, ylabel in (
                ("episode_return", "Training curves: episode return", "episode return"),
                (
                    "eval_nominal_return",
                    "Periodic evaluation: nominal return",
                    "nominal return",
                ),
                (
                    "eval_worst_case",
                    "Periodic evaluation: worst case (coarse mesh)",
                    "worst-case return",
                ),
            ):
                path = plot_curves(
                    curves, metric, steps, out / f"curves_{metric}.png", ylabel, colour, names,
                    titles, keep,
                )  # fmt: skip
                if path is not None:
                    note = " (a reference holds no curves)" if theirs else ""
                    figures.append((caption + _band_caption(curves, metric) + note, path))
        for task in summary["tasks"]:
            if len(ev) and (ev["task"] == task).any():
                lines = [
                    (f"{marked(summary, r)}: average over the set", r[1], c["mean"])
                    for r in theirs
                    if (c := cell(summary, r, task, "average_case")) and c.get("mean") is not None
                ]
                path = plot_over_set(
                    ev, task, out / f"returns_{task}.png", colour, summary["uncertainty"],
                    names, lines, titles, keep,
                )  # fmt: skip
                if path is not None:
                    note = (
                        "; reference rows: their average over the set, dashed, in a darker shade"
                        if lines
                        else ""
                    )
                    figures.append((f"Return over the uncertainty set: {task}{note}", path))
                path = plot_heatmaps(
                    ev, task, out / f"heatmap_{task}.png", summary["uncertainty"], names,
                    titles, keep,
                )  # fmt: skip
                if path is not None:
                    caption = f"Mean return over the 2-D set, per algorithm: {task}"
                    figures.append(
                        (caption + " (axes bounded by the set, dashed; x: the worst point)", path)
                    )
        figures += aggregate_figures(tables, summary, out, reference, keep)
    return figures


def _band_caption(curves: Any, metric: str) -> str:
    runs = curves.dropna(subset=[metric]).groupby(["task", "algorithm"])["seed"].nunique()
    if len(runs) and runs.min() < MIN_BAND_SEEDS:
        return (
            f" (mean over seeds; 95% t band only from {MIN_BAND_SEEDS} seeds on, "
            "fewer seeds drawn as thin lines)"
        )
    return " (mean and 95% t interval over seeds)"
