"""One look for every figure of the report, legible in a two-column paper.

- colours: Okabe & Ito's eight colour-blind-safe colours, then Paul Tol's "muted" ten (also
  colour-blind-safe), so up to 18 algorithms never share a colour; the paper's algorithms keep
  the same colour in every figure and every report, others follow in sorted order; markers and
  line styles cycle too, so a figure also reads in grey;
- fonts sized for a 3.3 in (one column) panel: 8 pt text, 7 pt ticks and legends;
- every figure is written as a PNG (for report.md) and a vector PDF beside it (for the paper),
  with TrueType fonts embedded (``pdf.fonttype`` 42: journals refuse Type 3).
"""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path
from typing import Any

from rrls.experiments.names import ORDER, sort_algos

__all__ = ["PALETTE", "RC", "colours", "markers", "pyplot", "save"]

OKABE_ITO = ("#E69F00", "#56B4E9", "#009E73", "#0072B2", "#D55E00", "#CC79A7", "#000000", "#F0E442")
TOL_MUTED = (
    "#CC6677",
    "#332288",
    "#DDCC77",
    "#117733",
    "#88CCEE",
    "#882255",
    "#44AA99",
    "#999933",
    "#AA4499",
    "#DDDDDD",
)
#: light colours (yellow, sand, pale grey) are hard to see on white: used last
LIGHT = ("#F0E442", "#DDCC77", "#DDDDDD")
PALETTE = tuple(c for c in OKABE_ITO + TOL_MUTED if c not in LIGHT) + LIGHT
MARKERS = ("o", "s", "^", "D", "v", "P", "X", "*", "<", ">")
RC = {
    "font.size": 8,
    "axes.titlesize": 8,
    "axes.labelsize": 8,
    "xtick.labelsize": 7,
    "ytick.labelsize": 7,
    "legend.fontsize": 7,
    "legend.title_fontsize": 7,
    "figure.titlesize": 9,
    "lines.linewidth": 1.4,
    "axes.spines.top": False,
    "axes.spines.right": False,
    "pdf.fonttype": 42,
    "ps.fonttype": 42,
}
PANEL = (3.3, 2.4)  # inches: one column of a two-column paper


def pyplot() -> Any:
    """matplotlib's pyplot (headless); draw inside ``pyplot().rc_context(RC)`` for the style
    (a context, so that the report does not restyle the caller's own figures)."""
    from rrls.evaluation.result_plot import pyplot as headless

    return headless()


def colours(algos: Iterable[str]) -> dict[str, str]:
    """A distinct colour per algorithm: the paper's first (fixed), then the others sorted."""
    known = {a: i for i, a in enumerate(ORDER)}
    others = [a for a in sort_algos(algos) if a not in known]
    index = {**known, **{a: len(ORDER) + i for i, a in enumerate(sorted(others))}}
    return {a: PALETTE[index[a] % len(PALETTE)] for a in sort_algos(algos)}


def markers(algos: Iterable[str]) -> dict[str, str]:
    """A marker per algorithm (cycling), for figures read in grey."""
    return {a: MARKERS[i % len(MARKERS)] for i, a in enumerate(sort_algos(algos))}


def save(fig: Any, path: Path) -> Path:
    """``path`` (PNG, 200 dpi) and the same figure as a vector PDF beside it. The PDF carries
    no creation date, so the same data give the same bytes (a regenerated report whose data
    did not change leaves its committed figures alone)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=200, bbox_inches="tight")
    fig.savefig(path.with_suffix(".pdf"), bbox_inches="tight", metadata={"CreationDate": None})
    return path
