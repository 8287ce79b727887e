"""The report's tables: LaTeX for papers, CSV for scripts, markdown for ``report.md`` and text
for the terminal, all from ``summary.json`` and all with the reference's rows.

LaTeX: ``tables/<name>.tex`` is a booktabs ``tabular`` that ``\\input`` drops into a paper's
own ``table`` float, scaled down to ``\\linewidth`` only when wider (``\\resizebox``: needs
``booktabs`` and ``graphicx``, nothing else). Every cell of a table is one statistic
(``rrls report --cells``): ``ci`` (the default) ``mean [95 % CI]``, ``pm`` ``mean ± std`` (the
paper's style), the Average column included. Bold: per column, the highest mean and every row
whose 95 % interval overlaps it (a tie), over every row shown except those marked ‡ (another
training budget: not ranked). The notes (marks, bold rule, seeds, budget, statistic) are in the
suggested caption of the file's header, not inside the tabular. Rows: the paper's order (TD3,
DR, M2TD3, RARL, NR-MDP), then the others, the raw tables as the normalised ones; the reference's
rows (``TD3 (ref. quick)``) follow a rule. ``rrls report --rename NAME=TEXT`` renames a row
(``NAME@REF`` a reference's); a renamed row keeps its ‡. A table without a row is not written
(``write_tables`` says why).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from rrls.algorithms import plays_adversary
from rrls.report.caveats import BUDGET, budget_differs, few_seeds, is_unstable
from rrls.report.cells import average, ci, pm, tied_best
from rrls.report.latex import CELLS, PACKAGES, caption, fit, tex_escape
from rrls.report.names import display_name, normaliser_names, sort_algos, task_name

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


def label(summary: dict[str, Any], algo: str, source: str = "results") -> str:
    """A row's name in every table and figure: ``--rename``'s text, else its name (a submitted
    algorithm marked, a reference's named), then ‡ when its training budget is not the
    benchmark's: a rename never hides the mark."""
    renamed = summary.get("labels") or {}
    if source == "results":
        name = renamed.get(algo) or display_name(algo)
        submitted = any(s["algorithm"] == algo for s in summary.get("submitted") or [])
        if submitted and not renamed.get(algo):
            name += " (submitted)"
    else:
        ref = (summary.get("reference") or {}).get("name")
        name = renamed.get(f"{algo}@{ref}") or f"{display_name(algo)} (ref. {ref})"
    differs = budget_differs(summary, algo, source) and not name.endswith(BUDGET)
    return name + (BUDGET if differs else "")


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
    algos = list(
        dict.fromkeys(a for by in (summary.get("reference_results") or {}).values() for a in by)
    )
    theirs = [
        (label(summary, a, "reference_results"), a, "reference_results")
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
    """The paper's "Average" column of a normalised table (``cells.average``)."""
    return average([cell(summary, row, t, getter) for t in summary["tasks"]])


def write_tables(
    summary: dict[str, Any], out: Path, paper: dict[str, Any], cells: str = "ci"
) -> tuple[list[Path], dict[str, str]]:
    """``tables/<name>.tex`` (cells ``cells``: ``ci`` or ``pm``) and ``.csv`` of every table
    with a row; and, for those not written, why."""
    import pandas as pd

    from rrls.files import atomic_write_bytes, atomic_write_table

    if cells not in CELLS:
        raise ValueError(f"cells {cells!r}; valid: {', '.join(CELLS)}")
    out.mkdir(parents=True, exist_ok=True)
    written, skipped = [], {}
    same_protocol = summary["uncertainty"] == paper["uncertainty"]
    ref_name = (summary.get("reference") or {}).get("name")
    for name, (_, getter, _) in TABLES.items():
        rows = table_rows(summary, name)
        if not _filled(summary, rows, getter):
            skipped[name] = _why_empty(summary, name)
            for stale in (f"{name}.tex", f"{name}.csv"):
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
                        "label": row[0],
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
                        "other_budget": BUDGET in row[0],
                    }
                )
        atomic_write_table(out / f"{name}.csv", pd.DataFrame(records))
        text = _tex(summary, name, rows, paper, cells)
        atomic_write_bytes(out / f"{name}.tex", text.encode())
        written += [out / f"{name}.tex", out / f"{name}.csv"]
    return written, skipped


def _why_empty(summary: dict[str, Any], name: str) -> str:
    if name == "dynamic":
        return (
            "no run was evaluated against its own adversary (only RARL and NR-MDP train one; "
            "run them to fill paper Table 6)"
        )
    if name.startswith("normalised"):
        pair = " and ".join(normaliser_names())
        return (
            f"no task could be normalised: it needs finished {pair} runs here or a "
            "reference with them (`rrls report DIR --reference FILE`)"
        )
    return "no finished run"


def _tex(
    summary: dict[str, Any], name: str, rows: list[Row], paper: dict[str, Any], family: str
) -> str:
    """One table: its header (the packages, the suggested float and caption with every note),
    then the booktabs ``tabular``, scaled to the line only when wider (``fit``)."""
    title, getter, digits = TABLES[name]
    tasks = summary["tasks"]
    normalised = name.startswith("normalised")
    metric = getter[2:] if normalised else getter
    formatter = CELLS[family][0]
    # Table 6 as the paper prints it: each task in its own unit (10^k), no bold (the paper:
    # the two algorithms play different adversaries, so no ranking)
    scale = {t: paper["dynamic_scale"].get(t, 1.0) if name == "dynamic" else 1.0 for t in tasks}
    grid = []  # per row: its cells, scaled, the Average last
    for row in rows:
        line = [_scaled(cell(summary, row, t, getter), scale[t]) for t in tasks]
        grid.append([*line, average(line)] if normalised else line)
    ranked = name != "dynamic" and len(rows) > 1
    columns = list(zip(*grid)) if grid else []
    bold = [
        tied_best([c if BUDGET not in rows[i][0] else None for i, c in enumerate(col)])
        if ranked
        else [False] * len(rows)
        for col in columns
    ]
    cols = [
        task_name(t) + (f" ($10^{round(np.log10(scale[t]))}$)" if scale[t] != 1 else "")
        for t in tasks
    ] + (["Average"] if normalised else [])
    body = [
        "\\begin{tabular}{l" + "c" * len(cols) + "}",
        "\\toprule",
        " & " + " & ".join(cols) + " \\\\",
        "\\midrule",
    ]
    few = unstable_seen = False
    own = sum(r[2] == "results" for r in rows)
    for i, row in enumerate(rows):
        if i == own and i:
            body.append("\\midrule")
        texts = []
        for j, c in enumerate(grid[i]):
            unstable = normalised and j < len(tasks) and is_unstable(summary, tasks[j], metric)
            few |= few_seeds(c)
            unstable_seen |= bool(unstable and c and c.get("mean") is not None)
            texts.append(formatter(c, digits, bold=bold[j][i], unstable=unstable))
        body.append(f"{tex_escape(row[0])} & " + " & ".join(texts) + " \\\\")
    body += ["\\bottomrule", "\\end{tabular}"]
    seeds = sorted(
        {
            int(c["n_seeds"] or 0)
            for r in grid
            for c in r[: len(tasks)]
            if c and c.get("mean") is not None
        }
    )
    marks = {"ranked": ranked, "few": few, "unstable": unstable_seen}
    marks["scaled"] = any(v != 1 for v in scale.values())
    text = caption(
        summary, title, metric if name != "dynamic" else "dynamic", rows, family, seeds, marks
    )
    packages = " and ".join(f"\\usepackage{{{p}}}" for p in PACKAGES)
    header = [
        f"% {title}: {CELLS[family][1]} over seeds -- generated by `rrls report --cells {family}`",
        f"% needs {packages} (\\resizebox: the tabular is scaled down to \\linewidth only "
        "when wider)",
        "% the table's notes are its suggested caption; in a paper:",
        "% \\begin{table}[tbp]",
        "% \\centering",
        f"% \\caption{{{text}}}",
        f"% \\label{{tab:rrls-{name}}}",
        f"% \\input{{{name}}}",
        "% \\end{table}",
    ]
    return "\n".join(header + fit(body)) + "\n"


def _scaled(c: dict[str, Any] | None, scale: float) -> dict[str, Any] | None:
    if not c or c.get("mean") is None or scale == 1:
        return c
    return {
        **c,
        **{k: None if c.get(k) is None else c[k] / scale for k in ("mean", "std")},
        "ci95": None if not c.get("ci95") else [v / scale for v in c["ci95"]],
    }


def md_table(summary: dict[str, Any], name: str, paper: dict[str, Any]) -> list[str]:
    """Table ``name`` for ``report.md``: ``mean ± std`` (the paper's number beside it under
    the paper's protocol), the reference's rows after the benchmark's."""
    from rrls.report.cells import fmt

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
