"""How one cell of a table reads: in markdown, in the terminal and in LaTeX, as ``mean ± std``
(the paper's style) or ``mean [95 % CI]``, with its caveats beside it.

Why one module: the caveats (``rrls.report.caveats``) must mark a cell the same way in
every output — fewer than 3 seeds (†), one seed (its value alone, never "± 0.00"), an unstable
normalisation (§) — so every table formats its cells here.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from rrls.report.caveats import FEW, UNSTABLE, few_seeds

__all__ = ["average", "ci", "fmt", "interval", "overlaps", "pm", "tex_ci", "tex_pm", "tied_best"]

Cell = dict[str, Any] | None


def fmt(value: float | None, digits: int = 2) -> str:
    """A number for a table: ``–`` when missing, never ``-0.00``."""
    if value is None or not np.isfinite(value):
        return "–"
    return f"{round(value, digits) + 0.0:,.{digits}f}"  # + 0.0: no "-0.00"


def _marks(cell: dict[str, Any], unstable: bool) -> str:
    return (FEW if few_seeds(cell) else "") + (UNSTABLE if unstable else "")


def _one_seed(cell: dict[str, Any]) -> bool:
    return cell.get("n_seeds") == 1 or cell.get("std") is None


def pm(cell: Cell, digits: int = 2, unstable: bool = False) -> str:
    """``mean ± std`` (one seed: its value alone), then its marks."""
    if not cell or cell.get("mean") is None:
        return "–"
    body = fmt(cell["mean"], digits)
    if not _one_seed(cell):
        body += f" ± {fmt(cell['std'], digits)}"
    return body + _marks(cell, unstable)


def ci(cell: Cell, digits: int = 2, unstable: bool = False) -> str:
    """``mean [lo, hi]`` (the 95 % t interval of the mean; without one, the mean alone),
    then its marks."""
    if not cell or cell.get("mean") is None:
        return "–"
    body = fmt(cell["mean"], digits)
    interval = cell.get("ci95")
    if interval:
        body += f" [{fmt(interval[0], digits)}, {fmt(interval[1], digits)}]"
    return body + _marks(cell, unstable)


def _tex_marks(cell: dict[str, Any], unstable: bool) -> str:
    marks = ("\\dagger" if few_seeds(cell) else "") + ("\\S" if unstable else "")
    return f"^{{{marks}}}" if marks else ""


def _tex_num(value: float, digits: int) -> str:
    return f"{round(value, digits) + 0.0:.{digits}f}"


def tex_pm(cell: Cell, digits: int = 2, bold: bool = False, unstable: bool = False) -> str:
    """``$mean \\pm std$`` (one seed: ``$mean$``), bold when best, with its marks."""
    if not cell or cell.get("mean") is None:
        return "--"
    body = _tex_num(cell["mean"], digits)
    if not _one_seed(cell):
        body += f" \\pm {_tex_num(cell['std'], digits)}"
    body += _tex_marks(cell, unstable)
    return f"$\\mathbf{{{body}}}$" if bold else f"${body}$"


def tex_ci(cell: Cell, digits: int = 2, bold: bool = False, unstable: bool = False) -> str:
    """``$mean\\,[lo, hi]$`` (the 95 % CI of the mean; the mean alone without one), the mean
    bold when best, with its marks."""
    if not cell or cell.get("mean") is None:
        return "--"
    mean = _tex_num(cell["mean"], digits)
    body = f"\\mathbf{{{mean}}}" if bold else mean
    interval = cell.get("ci95")
    if interval:
        body += f"\\,[{_tex_num(interval[0], digits)}, {_tex_num(interval[1], digits)}]"
    return f"${body}{_tex_marks(cell, unstable)}$"


def interval(cell: Cell) -> tuple[float, float] | None:
    """A cell's 95 % interval of the mean; without one (one seed, a reference row without
    per-seed values), its mean as a point; None without a mean."""
    if not cell or cell.get("mean") is None:
        return None
    lo, hi = cell.get("ci95") or (cell["mean"], cell["mean"])
    return float(lo), float(hi)


def overlaps(a: Cell, b: Cell) -> bool:
    """Whether the intervals (``interval``) of two cells share a value."""
    x, y = interval(a), interval(b)
    return x is not None and y is not None and x[0] <= y[1] and y[0] <= x[1]


def tied_best(cells: list[Cell]) -> list[bool]:
    """Which of a column's cells are bold: the highest mean and every cell whose interval
    overlaps that cell's (a tie the seeds cannot separate). ``None`` entries are not ranked."""
    ranked = [c for c in cells if c and c.get("mean") is not None]
    if not ranked:
        return [False] * len(cells)
    best = max(ranked, key=lambda c: c["mean"])
    return [c is not None and overlaps(c, best) for c in cells]


def average(cells: list[Cell]) -> Cell:
    """The paper's "Average" column over a row's task cells: the mean of the means and the
    mean of the stds (its ``mean ± std``), and a 95 % interval of that mean: the task means are
    independent, so its variance is the sum of their squared standard errors over T², read
    back from each task's t interval, with Welch-Satterthwaite degrees of freedom (one task:
    that task's interval). No interval unless every task has one."""
    from scipy.stats import t

    cells = [c for c in cells if c and c.get("mean") is not None]
    if not cells:
        return None
    stds = [c["std"] for c in cells if c.get("std") is not None]
    out = {
        "mean": float(np.mean([c["mean"] for c in cells])),
        "std": float(np.mean(stds)) if len(stds) == len(cells) else None,
        "n_seeds": min(int(c.get("n_seeds") or 0) for c in cells),
        "ci95": None,
    }
    ns = [int(c.get("n_seeds") or 0) for c in cells]
    if all(c.get("ci95") for c in cells) and min(ns) >= 2:
        var = np.array(
            [
                ((c["ci95"][1] - c["ci95"][0]) / 2 / t.ppf(0.975, n - 1)) ** 2
                for c, n in zip(cells, ns)
            ]
        )
        total = var.sum()
        if total > 0:
            df = total**2 / sum(v**2 / (n - 1) for v, n in zip(var, ns))
            half = float(t.ppf(0.975, df) * np.sqrt(total) / len(cells))
        else:
            half = 0.0
        out["ci95"] = [out["mean"] - half, out["mean"] + half]
    return out
