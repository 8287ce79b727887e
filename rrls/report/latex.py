"""What a report's ``.tex`` table needs to go into a paper unedited: its cells' statistic, a
caption that says everything a reader of the table alone must know (score, statistic, seeds,
budget, bold rule, every mark), a box that never overflows the line, and row names escaped.

Why apart from ``rrls.report.tables``: the tables choose rows and cells; this module only
writes LaTeX, with ``booktabs`` and ``graphicx`` as the only packages a paper needs.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from rrls.report.caveats import BUDGET, BUDGET_TEX_MARK, FEW_SEEDS_TEX, UNSTABLE_TEX
from rrls.report.cells import tex_ci, tex_pm
from rrls.report.names import normaliser_names, task_name

__all__ = ["CELLS", "PACKAGES", "caption", "fit", "fit_file", "tex_escape"]

#: the packages a paper's preamble needs for every table the report writes
PACKAGES = ("booktabs", "graphicx")
#: ``rrls report --cells``: (formatter, what a cell is, in a caption); ``ci`` the default
CELLS = {
    "ci": (tex_ci, "mean and 95\\% Student-$t$ confidence interval of the mean"),
    "pm": (tex_pm, "mean $\\pm$ standard deviation (ddof 0)"),
}
#: what a table's caption calls its score
SCORE_TEXT = {
    "worst_case": "worst case: a run's lowest mean return over the set's mesh points",
    "average_case": "average case: a run's mean return over the set's mesh points",
    "dynamic": "a run's mean return against its own trained adversary",
}
#: (label, algorithm, the summary's cells it reads), as ``rrls.report.tables.Row``
Row = tuple[str, str, str]


def caption(
    summary: dict[str, Any],
    title: str,
    metric: str,
    rows: list[Row],
    family: str,
    seeds: list[int],
    marks: dict[str, bool],
) -> str:
    """A table's caption: the score and protocol, the statistic over how many seeds, the
    training budget, the bold rule, the reference's rows and every mark the table uses
    (``marks``: ``ranked``, ``few``, ``unstable``, ``scaled``)."""
    spec = summary.get("benchmark") or {}
    normalised = title.startswith("Normalised")
    where = ""
    by_task = spec.get("by_task") or {}
    if spec:
        episodes = spec.get("episodes")
        where = f"; set {tex_escape(str(spec['uncertainty']))}, {spec['mesh']} mesh points per " + (
            f"dimension, {episodes} episode{'s' * (episodes != 1)} per point"
            if episodes
            else "dimension"
        )
    text = [f"{title.split(' (paper')[0]} ({SCORE_TEXT[metric]}{where})."]
    n = "?" if not seeds else str(seeds[0]) if len(seeds) == 1 else f"{seeds[0]}--{seeds[-1]}"
    text.append(f"Each cell: {CELLS[family][1]} over {n} seed{'s' * (n != '1')}.")
    if spec.get("steps") and not by_task:
        text.append(f"Training budget: {spec['steps']:,} steps per run.")
    elif by_task:  # joined benchmarks: each task's own budget, seeds and episodes
        text.append(
            "Each task from its own benchmark: "
            + "; ".join(
                f"{tex_escape(task_name(t))} {t_['steps']:,} steps per run, "
                f"{len(t_['seeds'])} seeds, {t_['episodes']} episodes per point"
                for t, t_ in by_task.items()
            )
            + "."
        )
    zero, one = (tex_escape(name) for name in normaliser_names())
    if normalised:
        text.append(
            f"Normalised score: $(v - v_{{\\mathrm{{{zero}}}}}) / |v_{{\\mathrm{{{one}}}}} - "
            f"v_{{\\mathrm{{{zero}}}}}|$ with the {zero} and {one} seed means."
        )
        text.append(
            "Average: mean over tasks of the means $\\pm$ mean of the stds."
            if family == "pm"
            else "Average: mean over tasks of the means with the 95\\% $t$ interval from the "
            "tasks' standard errors (Welch--Satterthwaite)."
        )
    budget = any(BUDGET in r[0] for r in rows)
    if marks.get("ranked"):
        text.append(
            "Bold: in each column the highest mean and every row whose 95\\% confidence "
            "interval overlaps its interval (a tie; a cell without an interval: its mean)"
            + (f"; rows marked {BUDGET_TEX_MARK} are not ranked." if budget else ".")
        )
    elif metric == "dynamic":
        text.append("No bold: each algorithm plays its own adversary.")
    if marks.get("scaled"):
        text.append("A heading's ($10^k$): that column's values are in units of $10^k$.")
    ref = summary.get("reference") or {}
    if any(r[2] != "results" for r in rows):
        own = normalised and str(ref.get("normalised_by", "")).startswith("its")
        text.append(
            f"Rows ``(ref.\\ {tex_escape(str(ref.get('name')))})'': "
            f"{tex_escape(str(ref.get('label')))}"
            + (f", normalised by its own {zero} and {one}." if own else ".")
        )
    if marks.get("few"):
        text.append(FEW_SEEDS_TEX)
    if marks.get("unstable") and normalised:
        text.append(UNSTABLE_TEX)
    if budget:
        text.append(
            f"{BUDGET_TEX_MARK} another training budget than this benchmark's, not a "
            f"like-for-like comparison: {_budgets(summary, rows)}."
        )
    return " ".join(text)


def _budgets(summary: dict[str, Any], rows: list[Row]) -> str:
    """Each ‡ row's training steps, in words for a caption."""

    def steps(value: Any) -> str:
        return f"{value:,}" if value else "not stated"

    parts = []
    for name, algo, source in rows:
        if BUDGET not in name or source != "results":
            continue
        values = [*((summary.get("run_steps") or {}).get(algo) or [])]
        values += [r.get("steps") for r in summary.get("submitted") or [] if r["algorithm"] == algo]
        shown = ", ".join(steps(v) for v in sorted(set(values), key=lambda v: v or 0))
        parts.append(f"{tex_escape(name.removesuffix(BUDGET))} {shown}")
    ref = summary.get("reference") or {}
    if any(BUDGET in name and source != "results" for name, _, source in rows):
        parts.append(f"the reference's rows {steps(ref.get('steps'))}")
    return "; ".join(parts) + " steps"


def fit(tabular: list[str]) -> list[str]:
    """``tabular``'s lines boxed and, only when wider than the line, scaled down to it
    (``\\resizebox``, graphicx): a table never overflows the text, a narrow one keeps its size."""
    return [
        "\\ifdefined\\rrlsfit\\else\\newsavebox\\rrlsfit\\fi",
        "\\sbox\\rrlsfit{%",
        *tabular[:-1],
        tabular[-1] + "}%",
        "\\noindent\\ifdim\\wd\\rrlsfit>\\linewidth",
        "\\resizebox{\\linewidth}{!}{\\usebox\\rrlsfit}\\else\\usebox\\rrlsfit\\fi",
    ]


def fit_file(path: Path) -> None:
    """Rewrite a generated ``.tex`` whose ``tabular`` is bare with it ``fit`` to the line."""
    from rrls.files import atomic_write_bytes

    lines = Path(path).read_text().splitlines()
    if any("\\rrlsfit" in line for line in lines):
        return
    start = next(i for i, line in enumerate(lines) if line.startswith("\\begin{tabular}"))
    end = max(i for i, line in enumerate(lines) if line.startswith("\\end{tabular}"))
    note = "% scaled down to \\linewidth only when wider: needs \\usepackage{graphicx}"
    out = [*lines[:start], note, *fit(lines[start : end + 1]), *lines[end + 1 :]]
    atomic_write_bytes(Path(path), ("\n".join(out) + "\n").encode())


_TEX_SPECIAL = {
    BUDGET: BUDGET_TEX_MARK,
    "\\": r"\textbackslash{}",
    "&": r"\&",
    "%": r"\%",
    "$": r"\$",
    "#": r"\#",
    "_": r"\_",
    "{": r"\{",
    "}": r"\}",
    "~": r"\textasciitilde{}",
    "^": r"\textasciicircum{}",
}


def tex_escape(text: str) -> str:
    """``text`` as LaTeX prints it literally (a row name such as ``my_sac``); the budget mark
    ‡ as ``$^{\\ddagger}$``."""
    return "".join(_TEX_SPECIAL.get(ch, ch) for ch in text)
