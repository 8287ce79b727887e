"""How one cell of a table reads: in markdown, in the terminal and in LaTeX, as ``mean ± std``
(the paper's style) or ``mean [95 % CI]``, with its caveats beside it.

Why one module: the caveats (``rrls.experiments.caveats``) must mark a cell the same way in
every output — fewer than 3 seeds (†), one seed (its value alone, never "± 0.00"), an unstable
normalisation (§) — so every table formats its cells here.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from rrls.experiments.caveats import FEW, UNSTABLE, few_seeds

__all__ = ["ci", "fmt", "pm", "tex_ci", "tex_pm"]

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
