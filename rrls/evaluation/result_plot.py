"""Return over the uncertainty set, drawn from an evaluation's saved table (never from a live run).

1D: mean return per point (± std over episodes, episodes as dots). 2D: a heatmap of the mean.
3D: the three 2D slices through the worst mesh point. Needs matplotlib (the ``plot`` extra).
"""

from __future__ import annotations

import io
from pathlib import Path
from typing import Any

import numpy as np

from rrls.evaluation.result import EvaluationResult
from rrls.extras import install_hint
from rrls.files import atomic_write_bytes


def pyplot() -> Any:
    try:
        import matplotlib
    except ImportError as err:
        raise ImportError(f"plots need matplotlib: {install_hint('plot')}") from err
    matplotlib.use("Agg")  # files only: works on headless machines
    import matplotlib.pyplot as plt

    return plt


def plot_result(result: EvaluationResult | str | Path, path: str | Path | None = None) -> Path:
    """Draw ``result`` (or the evaluation saved in a directory) to a PNG; returns its path."""
    if not isinstance(result, EvaluationResult):
        out_dir = Path(result)
        result = EvaluationResult.load(out_dir)
        path = path or out_dir / "returns.png"
    if path is None:
        raise ValueError("give a path for the PNG when plotting an in-memory result")
    plt = pyplot()
    names = result.param_names
    table = result.per_point
    title = (
        f"{_policy_name(result.config)} on {result.task} / "
        f"{result.config.get('uncertainty_name', '')}: worst case "
        f"{result.worst_case:.1f}, average case {result.average_case:.1f}"
    )
    if len(names) == 0:
        raise ValueError("a nominal-only evaluation has a single point: nothing to plot")
    if len(names) == 1:
        fig, ax = plt.subplots(figsize=(6, 4))
        _line(ax, result, names[0])
    elif len(names) == 2:
        fig, ax = plt.subplots(figsize=(6, 5))
        mesh = _heatmap(ax, table, names[0], names[1], result.worst_point, box=result.uncertainty)
        fig.colorbar(mesh, ax=ax, label="mean return")
    else:
        worst = result.worst_point
        pairs = [(a, b) for i, a in enumerate(names) for b in names[i + 1 :]]
        fig, axes = plt.subplots(
            1, len(pairs), figsize=(5.5 * len(pairs), 4.8), squeeze=False, layout="constrained"
        )
        # one colour scale for every slice (the whole mesh's range), so colours compare
        limits = (float(table["mean_return"].min()), float(table["mean_return"].max()))
        for ax, (a, b) in zip(axes[0], pairs):
            fixed = {n: worst[n] for n in names if n not in (a, b)}
            mask = np.ones(len(table), dtype=bool)
            for n, v in fixed.items():
                mask &= np.isclose(table[n].to_numpy(), v)
            mesh = _heatmap(ax, table[mask], a, b, worst, limits, result.uncertainty)
            ax.set_title(", ".join(f"{n} = {v:.3g}" for n, v in fixed.items()), fontsize=9)
        fig.colorbar(mesh, ax=list(axes[0]), label="mean return (all slices)")
    fig.suptitle(title, fontsize=10)
    if len(names) < 3:  # the 3D figure lays itself out (constrained, shared colorbar)
        fig.tight_layout()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    buffer = io.BytesIO()  # written whole or not at all (Ctrl-C, a full disk)
    fig.savefig(buffer, dpi=120, format=path.suffix.lstrip(".").lower() or None)
    plt.close(fig)
    atomic_write_bytes(path, buffer.getvalue())
    return path


def _line(ax: Any, result: EvaluationResult, name: str) -> None:
    table = result.per_point.sort_values(name)
    x, mean = table[name].to_numpy(), table["mean_return"].to_numpy()
    std = np.nan_to_num(table["std_return"].to_numpy())
    ax.fill_between(x, mean - std, mean + std, alpha=0.2, label="± std over episodes")
    ax.plot(x, mean, marker="o", label="mean return")
    ax.scatter(
        result.episodes[name],
        result.episodes["return"],
        s=6,
        alpha=0.4,
        color="gray",
        label="episodes",
    )
    i = int(np.argmin(mean))
    ax.scatter([x[i]], [mean[i]], color="red", zorder=3, label="worst case")
    ax.set_xlabel(name)
    ax.set_ylabel("return")
    ax.legend(fontsize=8)


def _heatmap(
    ax: Any,
    table: Any,
    a: str,
    b: str,
    worst: dict[str, float],
    limits: tuple[float, float] | None = None,
    box: Any = None,
) -> Any:
    """The mean return over two axes: every mesh point a full cell centred on it, the set's
    bounds (``box``) drawn as a dashed outline."""
    grid = table.pivot_table(index=b, columns=a, values="mean_return")
    xs, ys = grid.columns.to_numpy(dtype=float), grid.index.to_numpy(dtype=float)
    vmin, vmax = limits if limits is not None else (None, None)
    mesh = ax.pcolormesh(
        cell_edges(xs),
        cell_edges(ys),
        grid.to_numpy(),
        shading="flat",
        cmap="viridis",
        vmin=vmin,
        vmax=vmax,
    )
    if box is not None and a in box.names and b in box.names:
        outline_box(ax, box.to_dict(box.low), box.to_dict(box.high), a, b)
    ax.scatter([worst[a]], [worst[b]], marker="x", color="red", s=60, label="worst point")
    ax.set_xlabel(a)
    ax.set_ylabel(b)
    ax.legend(fontsize=8, loc="upper right")
    return mesh


def _policy_name(config: dict[str, Any]) -> str:
    """How a plot title names the evaluated policy: algorithm, training seed, file or run."""
    where = config.get("policy_run_dir") or config.get("policy_path")
    parts = [str(config["policy_algorithm"])] if config.get("policy_algorithm") else []
    if config.get("policy_seed") is not None:
        parts.append(f"seed {config['policy_seed']}")
    if where:
        parts.append(f"({Path(str(where)).resolve().name or where})")
    if not parts:
        parts.append(f"policy {config.get('policy_fingerprint', '?')}")
    return " ".join(parts)


def cell_edges(centres: np.ndarray) -> np.ndarray:
    """Cell edges around sorted mesh coordinates, for ``pcolormesh``: midpoints between
    neighbours, and half a spacing beyond the first and last point, so every cell has the
    width of its neighbours (a mesh point on a bound has its cell half outside the set: the
    set's bounds are drawn as an outline, ``outline_box``)."""
    c = np.asarray(centres, dtype=float)
    if len(c) == 1:
        return np.array([c[0] - 0.5, c[0] + 0.5])
    mid = (c[1:] + c[:-1]) / 2
    return np.concatenate([[c[0] - (c[1] - c[0]) / 2], mid, [c[-1] + (c[-1] - c[-2]) / 2]])


def outline_box(ax: Any, low: dict[str, float], high: dict[str, float], a: str, b: str) -> None:
    """The set's bounds on axes ``a`` (x) and ``b`` (y) as a dashed white rectangle."""
    from matplotlib.patches import Rectangle

    ax.add_patch(
        Rectangle(
            (low[a], low[b]), high[a] - low[a], high[b] - low[b],
            fill=False, ec="white", ls="--", lw=0.8, zorder=2,
        )
    )  # fmt: skip


__all__ = ["cell_edges", "outline_box", "plot_result", "pyplot"]
