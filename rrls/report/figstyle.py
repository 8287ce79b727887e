"""One look for every figure of the report, legible in a two-column paper.

- colours: Okabe & Ito's eight colour-blind-safe colours, then Paul Tol's "muted" ten (also
  colour-blind-safe), so up to 18 algorithms never share a colour; the paper's algorithms keep
  the same colour in every figure and every report, others follow in sorted order; markers and
  line styles cycle too, so a figure also reads in grey;
- fonts sized for a 3.3 in (one column) panel: 8 pt text, 7 pt ticks and legends;
- every figure is written as a PNG (for report.md) and a vector PDF beside it (for the paper),
  with TrueType fonts embedded (``pdf.fonttype`` 42: journals refuse Type 3);
- a reader needs no caption to read an axis or a legend: every numeric axis says its unit in
  brackets (``axis_label``; a parameter's from its field, ``param_unit``), legends sit framed
  outside the axes, never over data (``legend_outside``), and a reference's row is drawn in a
  shade of its algorithm's colour, dashed (``reference_colour``), so that "TD3" and
  "TD3 (ref. quick)" differ in colour and in style.
"""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path
from typing import Any

from rrls.report.names import ORDER, sort_algos

__all__ = [
    "PALETTE",
    "RC",
    "REFERENCE_LS",
    "RETURN",
    "STEPS",
    "axis_label",
    "colours",
    "keep_or_close",
    "legend_outside",
    "markers",
    "param_unit",
    "pyplot",
    "reference_colour",
    "save",
]

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
#: the line style of a reference's rows (the benchmark's own: solid)
REFERENCE_LS = "--"
#: the units of the axes every figure shares
RETURN = "sum of rewards"  # an episode's return
STEPS = "environment steps"
#: a field whose units are "-" (a friction coefficient) is a pure number
UNITLESS = "unitless"


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
    # the legends outside the layout (``legend_outside``) are in the picture all the same
    legends = [ax.get_legend() for ax in fig.axes if ax.get_legend() is not None]
    tight = {
        "bbox_inches": "tight",
        "bbox_extra_artists": [*fig.get_default_bbox_extra_artists(), *legends],
    }
    fig.savefig(path, dpi=200, **tight)
    fig.savefig(path.with_suffix(".pdf"), metadata={"CreationDate": None}, **tight)
    return path


def axis_label(quantity: str, unit: str, wrap: bool = False) -> str:
    """``quantity [unit]``: the unit in brackets, as parentheses already qualify quantities
    (``wrap``: on a line of its own, for a label wider than its panel)."""
    return f"{quantity}{chr(10) if wrap else ' '}[{unit}]"


def param_unit(task: str, name: str) -> str:
    """The unit of ``task``'s parameter ``name``, from its field in the task's table
    (``rrls.params.FIELDS``: kg for a mass, N for a force, a friction coefficient unitless)."""
    from rrls.params import FIELDS
    from rrls.registry import get_task

    try:
        spec = get_task(task)
    except ValueError:  # a task of a plug-in not installed here
        return "unit not known"
    for row in (*spec.params, *spec.forces):
        if name == row.name or name in row.aliases:
            unit = FIELDS[row.field].units
            return UNITLESS if unit == "-" else unit
    return "unit not known"


def reference_colour(colour: str) -> str:
    """A reference row's colour: its algorithm's, darkened (lightened if already dark), the
    same hue told apart from the benchmark's own row."""
    rgb = [int(colour.lstrip("#")[i : i + 2], 16) for i in (0, 2, 4)]
    if sum(rgb) < 200:  # black and near-black: towards white
        mixed = [round(c + 0.45 * (255 - c)) for c in rgb]
    else:
        mixed = [round(0.6 * c) for c in rgb]
    return "#" + "".join(f"{c:02X}" for c in mixed)


def legend_outside(ax: Any, **kwargs: Any) -> Any:
    """``ax``'s legend, framed, to the right of the axes: it never covers a line, and the
    saved figure (``bbox_inches="tight"``) grows to hold it, the panels keeping their width
    (out of the layout: ``tight_layout`` would shrink them to fit it)."""
    legend = ax.legend(
        loc="upper left",
        bbox_to_anchor=(1.02, 1.0),
        borderaxespad=0.0,
        frameon=True,
        framealpha=1.0,
        edgecolor="0.8",
        **kwargs,
    )
    legend.set_in_layout(False)
    return legend


def keep_or_close(fig: Any, path: Path, keep: dict[str, Any] | None) -> None:
    """Close a saved figure, or hand it to ``keep`` (by file name) for a caller to inspect."""
    if keep is None:
        pyplot().close(fig)
    else:
        keep[path.name] = fig
