"""The report's tables: LaTeX for papers, CSV for scripts, markdown for ``report.md`` and text
for the terminal, all from ``summary.json`` and all with the reference's rows.

LaTeX: ``tables/<name>.tex`` is a bare ``tabular`` (booktabs rules) that ``\\input`` drops into a
paper's own ``table`` float: algorithms × tasks, each cell ``mean [95 % CI]`` over seeds, the best
mean of a column over every row shown (the reference's included) in bold;
``tables/<name>_std.tex`` is the same table as ``mean ± std`` (the paper's style, to set beside
its Tables 4-8). The reference's rows (``TD3 (ref. quick)``: a source, not a task) follow a
rule; ``rrls report --rename NAME=TEXT`` renames a row (``NAME@REF`` a reference's). Row names
are LaTeX-escaped. The caveats are printed under the table, not only in a comment: † fewer
than 3 seeds, § an unstable normalisation. A table without a row is not written
(``write_tables`` says why).
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from rrls.algorithms import plays_adversary
from rrls.experiments.caveats import (
    BUDGET,
    BUDGET_TEX,
    FEW_SEEDS_TEX,
    UNSTABLE_TEX,
    budget_differs,
    few_seeds,
    is_unstable,
)
from rrls.experiments.cells import ci, pm, tex_ci, tex_pm
from rrls.experiments.names import display_name, sort_algos, task_name

__all__ = [
    "TABLES",
    "Row",
    "cell",
    "label",
    "md_table",
    "table_rows",
    "terminal_table",
    "tex_escape",
    "write_tables",
]

TABLES = {
    # name: (title, cell getter, digits)
    "raw_worst_case": ("Raw static worst case (paper Appendix, Table 7)", "worst_case", 2),
    "raw_average_case": ("Raw static average case (paper Appendix, Table 8)", "average_case", 2),
    "normalised_worst_case": ("Normalised static worst case (paper Table 4)", "n:worst_case", 2),
    "normalised_average_case": (
        "Normalised static average case (paper Table 5)",
        "n:average_case",
        2,
    ),
    "dynamic": ("Against the run's own adversary (paper Table 6)", "dynamic", 2),
}

#: (label, algorithm, the summary's cells it reads: "results" or "reference_results")
Row = tuple[str, str, str]


def label(summary: dict[str, Any], algo: str) -> str:
    """An algorithm's name in the report (``--rename`` first); submitted ones are marked."""
    renamed = (summary.get("labels") or {}).get(algo)
    if renamed:
        return renamed
    name = display_name(algo)
    if any(s["algorithm"] == algo for s in summary.get("submitted") or []):
        return f"{name} (submitted)" + (BUDGET if budget_differs(summary, algo) else "")
    return name


def cell(summary: dict[str, Any], row: Row, task: str, getter: str) -> dict[str, Any] | None:
    """The cell of ``row`` on ``task`` (``getter``: a score, ``n:score`` normalised, dynamic)."""
    found = (summary.get(row[2]) or {}).get(task, {}).get(row[1])
    if found is None:
        return None
    if getter.startswith("n:"):
        return found.get("normalised", {}).get(getter[2:])
    return found.get(getter)


def table_rows(summary: dict[str, Any], name: str) -> list[Row]:
    """The benchmark's rows of table ``name``, then the reference's (those with a cell)."""
    getter = TABLES[name][1]
    own = [
        (label(summary, a), a, "results")
        for a in summary["algorithms"]
        if name != "dynamic"
        or plays_adversary(a)
        or any("dynamic" in summary["results"][t].get(a, {}) for t in summary["tasks"])
    ]
    ref = summary.get("reference") or {}
    algos = list(
        dict.fromkeys(a for by in (summary.get("reference_results") or {}).values() for a in by)
    )
    renamed = summary.get("labels") or {}
    theirs = [
        (
            renamed.get(f"{a}@{ref.get('name')}") or f"{display_name(a)} (ref. {ref.get('name')})",
            a,
            "reference_results",
        )
        for a in sort_algos(algos)
        if any(cell(summary, ("", a, "reference_results"), t, getter) for t in summary["tasks"])
    ]
    return [*own, *theirs]


def _filled(summary: dict[str, Any], rows: list[Row], getter: str) -> bool:
    return any(
        (cell(summary, r, t, getter) or {}).get("mean") is not None
        for r in rows
        for t in summary["tasks"]
    )


def _average(summary: dict[str, Any], row: Row, getter: str) -> dict[str, Any] | None:
    """The paper's "Average" column of a normalised table: the mean over tasks of the cell
    means and of their stds (with the fewest seeds of a task, for the caveats)."""
    if row[2] == "results":
        agg = summary["aggregate"].get(row[1], {}).get(f"normalised_{getter[2:]}", {})
        return {
            "mean": agg.get("mean_over_tasks"),
            "std": agg.get("std_over_tasks"),
            "n_seeds": agg.get("min_seeds"),
        }
    cells = [cell(summary, row, t, getter) for t in summary["tasks"]]
    cells = [c for c in cells if c and c.get("mean") is not None]
    if not cells:
        return None
    stds = [c["std"] for c in cells if c.get("std") is not None]
    return {
        "mean": float(np.mean([c["mean"] for c in cells])),
        "std": float(np.mean(stds)) if len(stds) == len(cells) else None,
        "n_seeds": min(int(c.get("n_seeds") or 0) for c in cells),
    }


def write_tables(
    summary: dict[str, Any], out: Path, paper: dict[str, Any]
) -> tuple[list[Path], dict[str, str]]:
    """``tables/<name>.tex``, ``<name>_std.tex`` and ``.csv`` of every table with a row; and,
    for those not written, why."""
    import pandas as pd

    from rrls._io import atomic_write_bytes, atomic_write_table

    out.mkdir(parents=True, exist_ok=True)
    written, skipped = [], {}
    same_protocol = summary["uncertainty"] == paper["uncertainty"]
    ref_name = (summary.get("reference") or {}).get("name")
    for name, (_, getter, _) in TABLES.items():
        rows = table_rows(summary, name)
        if not _filled(summary, rows, getter):
            skipped[name] = _why_empty(summary, name)
            for stale in (f"{name}.tex", f"{name}_std.tex", f"{name}.csv"):
                (out / stale).unlink(missing_ok=True)
            continue
        records = []
        for row in rows:
            for task in summary["tasks"]:
                c = cell(summary, row, task, getter) or {}
                pub = paper.get(name, {}).get(row[1], {}).get(task) if same_protocol else None
                if row[2] != "results":
                    pub = None
                records.append(
                    {
                        "algorithm": row[1],
                        "source": "benchmark" if row[2] == "results" else ref_name,
                        "task": task,
                        "mean": c.get("mean"),
                        "std": c.get("std"),
                        "iqm": c.get("iqm"),
                        "ci95_low": (c.get("ci95") or [None, None])[0],
                        "ci95_high": (c.get("ci95") or [None, None])[1],
                        "n_seeds": c.get("n_seeds", 0),
                        "paper_mean": pub[0] if isinstance(pub, list) else pub,
                        "paper_std": pub[1] if isinstance(pub, list) else None,
                        "unstable_normalisation": getter.startswith("n:")
                        and is_unstable(summary, task, getter[2:]),
                    }
                )
        atomic_write_table(out / f"{name}.csv", pd.DataFrame(records))
        for suffix, formatter in (("", tex_ci), ("_std", tex_pm)):
            text = _tex(summary, name, rows, paper, formatter, suffix)
            atomic_write_bytes(out / f"{name}{suffix}.tex", text.encode())
            written.append(out / f"{name}{suffix}.tex")
        written.append(out / f"{name}.csv")
    return written, skipped


def _why_empty(summary: dict[str, Any], name: str) -> str:
    if name == "dynamic":
        return (
            "no run was evaluated against its own adversary (only RARL and NR-MDP train one; "
            "run them to fill paper Table 6)"
        )
    if name.startswith("normalised"):
        return (
            "no task could be normalised: it needs finished TD3 and M2TD3 runs here or a "
            "reference with them (`rrls report DIR --reference FILE`)"
        )
    return "no finished run"


def _tex(
    summary: dict[str, Any],
    name: str,
    rows: list[Row],
    paper: dict[str, Any],
    formatter: Callable[..., str],
    suffix: str,
) -> str:
    """One table as a bare booktabs ``tabular``, its caveats as a last row."""
    title, getter, digits = TABLES[name]
    tasks = summary["tasks"]
    normalised = name.startswith("normalised")
    metric = getter[2:] if normalised else getter
    # Table 6 as the paper prints it: each task in its own unit (10^k), no bold (the paper:
    # the two algorithms play different adversaries, so no ranking)
    scale = {t: paper["dynamic_scale"].get(t, 1.0) if name == "dynamic" else 1.0 for t in tasks}
    best = {}  # over every row shown, the reference's included (the note under the table)
    for task in tasks:
        means = [(cell(summary, r, task, getter) or {}).get("mean") for r in rows]
        finite = [m for m in means if m is not None]
        best[task] = max(finite) if finite else None
    cols = [
        task_name(t) + (f" ($10^{round(np.log10(scale[t]))}$)" if scale[t] != 1 else "")
        for t in tasks
    ] + (["Average"] if normalised else [])
    style = "mean [95\\% CI]" if suffix == "" else "mean $\\pm$ std"
    ref = summary.get("reference") or {}
    lines = [
        f"% {title}: {style} over seeds -- generated by `rrls report`",
        "% needs \\usepackage{booktabs}; in a paper:",
        f"% \\begin{{table}}\\centering\\caption{{{title}}}\\input{{{name}{suffix}}}"
        f"\\label{{tab:rrls-{name}}}\\end{{table}}",
        *(
            [
                f"% reference rows: {ref.get('label')}"
                + (f" ({ref['file']})" if ref.get("file") else "")
            ]
            if ref
            else []
        ),
        "\\begin{tabular}{l" + "c" * len(cols) + "}",
        "\\toprule",
        " & " + " & ".join(cols) + " \\\\",
        "\\midrule",
    ]
    few = unstable_seen = False
    own = sum(r[2] == "results" for r in rows)
    for i, row in enumerate(rows):
        if i == own and i:
            lines.append("\\midrule")
        cells = []
        for task in tasks:
            c = cell(summary, row, task, getter)
            is_best = (
                c is not None
                and c.get("mean") is not None
                and c["mean"] == best[task]
                and name != "dynamic"
                and len(rows) > 1
            )
            if c and c.get("mean") is not None and scale[task] != 1:
                c = {
                    **c,
                    **{
                        k: None if c.get(k) is None else c[k] / scale[task] for k in ("mean", "std")
                    },
                    "ci95": None if not c.get("ci95") else [v / scale[task] for v in c["ci95"]],
                }
            unstable = normalised and is_unstable(summary, task, metric)
            few |= few_seeds(c)
            unstable_seen |= bool(unstable and c and c.get("mean") is not None)
            cells.append(formatter(c, digits, bold=is_best, unstable=unstable))
        if normalised:
            avg = _average(summary, row, getter)
            few |= few_seeds(avg)
            cells.append(tex_pm(avg, digits))
        shown = tex_escape(row[0]).replace(BUDGET, "$^{\\ddagger}$")
        lines.append(f"{shown} & " + " & ".join(cells) + " \\\\")
    lines.append("\\bottomrule")
    notes = ([FEW_SEEDS_TEX] if few else []) + ([UNSTABLE_TEX] if unstable_seen else [])
    if any(BUDGET in r[0] for r in rows):
        notes.append(BUDGET_TEX)
    if name != "dynamic" and len(rows) > 1:
        notes.insert(0, "Bold: the highest mean of each column over every row shown.")
    if normalised:
        notes.append("Average: mean over tasks of the means $\\pm$ of the stds.")
    lines += [
        f"\\multicolumn{{{len(cols) + 1}}}{{l}}{{\\footnotesize {note}}} \\\\" for note in notes
    ]
    lines.append("\\end{tabular}")
    return "\n".join(lines) + "\n"


_TEX_SPECIAL = {
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
    """``text`` as LaTeX prints it literally (a row name such as ``my_sac``)."""
    return "".join(_TEX_SPECIAL.get(ch, ch) for ch in text)


def md_table(summary: dict[str, Any], name: str, paper: dict[str, Any]) -> list[str]:
    """Table ``name`` for ``report.md``: ``mean ± std`` (the paper's number beside it under
    the paper's protocol), the reference's rows after the benchmark's."""
    from rrls.experiments.cells import fmt

    title, getter, digits = TABLES[name]
    tasks = summary["tasks"]
    rows = table_rows(summary, name)
    if not _filled(summary, rows, getter):
        return []
    same_protocol = summary["uncertainty"] == paper["uncertainty"]
    normalised = name.startswith("normalised")
    metric = getter[2:] if normalised else getter
    head = ["algorithm", *[task_name(t) for t in tasks]] + (
        ["Average", "IQM [95% CI]"] if normalised else []
    )
    lines = [f"### {title}", "", "| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for row in rows:
        texts = [row[0]]
        for task in tasks:
            unstable = normalised and is_unstable(summary, task, metric)
            text = pm(cell(summary, row, task, getter), digits, unstable=unstable)
            pub = paper.get(name, {}).get(row[1], {}).get(task) if same_protocol else None
            if pub is not None and row[2] == "results":
                pub_text = f"{fmt(pub[0])} ± {fmt(pub[1])}" if isinstance(pub, list) else fmt(pub)
                text += f" (paper {pub_text})"
            texts.append(text)
        if normalised:
            texts.append(pm(_average(summary, row, getter)))
            agg = summary["aggregate"].get(row[1], {}) if row[2] == "results" else {}
            agg = agg.get(f"normalised_{metric}", {})
            iqm = {"mean": agg.get("iqm"), "ci95": agg.get("ci95"), "n_seeds": agg.get("min_seeds")}
            texts.append(ci(iqm))
        lines.append("| " + " | ".join(texts) + " |")
    return [*lines, ""]


def terminal_table(summary: dict[str, Any]) -> str:
    """The worst / average case per task and algorithm (the reference's rows after the
    benchmark's), ``mean ± std`` over seeds; one seed: its value alone."""
    width = max([len(r[0]) for r in table_rows(summary, "raw_worst_case")] + [10])
    head = (
        f"{'task':<18} {'algorithm':<{width}} {'seeds':>5} {'worst case':>20} {'average case':>20}"
    )
    lines = [head]
    for task in summary["tasks"]:
        for row in table_rows(summary, "raw_worst_case"):
            w, a = (cell(summary, row, task, m) for m in ("worst_case", "average_case"))
            if not w or w.get("mean") is None:
                continue
            lines.append(
                f"{task:<18} {row[0]:<{width}} {w.get('n_seeds') or '?':>5} "
                f"{pm(w, 1):>20} {pm(a, 1):>20}"
            )
    if any("†" in line for line in lines[1:]):
        lines.append("† fewer than 3 seeds: ± is not a confidence interval (one seed: its value)")
    return "\n".join(lines)
