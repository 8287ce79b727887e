"""The report's rechecked worst case: per task and algorithm, the paper's worst case beside the
same runs' worst case rechecked with fresh episodes and a low quantile of their point means
(``rrls.evaluation.recheck``), mean over seeds with its 95 % Student-t interval.

Shown only for runs whose ``result.json`` has them (a benchmark with ``recheck`` set, or runs
rechecked afterwards): a row says how many of its runs were rechecked."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from rrls.report.cells import ci
from rrls.report.names import sort_algos, task_name
from rrls.report.stats import describe, rng_for

__all__ = ["markdown", "summarise_rechecked"]

COLUMNS = {
    "worst_case": "worst case (the paper's)",
    "worst_case_rechecked": "rechecked",
    "worst_case_q": "low quantile",
}


def summarise_rechecked(runs: Any) -> dict[str, Any]:
    """``summary.json``'s ``rechecked``: ``{task: {algo: {column: cell}}}`` over the runs that
    were rechecked (``runs``: the store's runs table), and the quantile used."""
    if "worst_case_rechecked" not in runs or not runs["worst_case_rechecked"].notna().any():
        return {}
    done = runs[runs["worst_case_rechecked"].notna()]
    out: dict[str, Any] = {"quantile": sorted(set(done["recheck_quantile"].dropna()))}
    for task, by_task in done.groupby("task", sort=False):
        for algo in sort_algos(by_task["algorithm"]):  # the paper's row order
            rows = by_task[by_task["algorithm"] == algo]
            out.setdefault("tasks", {}).setdefault(task, {})[algo] = {
                col: describe(rows[col].to_numpy(dtype=float), rng_for(task, algo, col))
                for col in COLUMNS
            } | {"runs": int(len(runs[(runs.task == task) & (runs.algorithm == algo)]))}
    return out


def markdown(summary: Mapping[str, Any], name: Any = str) -> list[str]:
    """The report's section (nothing when no run was rechecked)."""
    data = summary.get("rechecked") or {}
    if not data.get("tasks"):
        return []
    q = ", ".join(f"{x * 100:g}th percentile" for x in data["quantile"]) or "a low quantile"
    lines = [
        "## Worst case, rechecked with fresh episodes",
        "",
        "The paper's worst case is the lowest of the mesh points' mean returns; with few "
        "episodes per point it picks the point whose episodes went worst by chance. Here each "
        "run's lowest points were re-evaluated with fresh, independent episodes (rechecked: the "
        f"lowest of those new means) and the {q} of its point means is given beside "
        "(mean over seeds [95 % t interval]). Far above the paper's statistic: its minimum was "
        "partly episode noise.",
        "",
        "| task | algorithm | runs rechecked | " + " | ".join(COLUMNS.values()) + " |",
        "|---|---|---|" + "---|" * len(COLUMNS),
    ]
    for task, by_algo in data["tasks"].items():
        for algo, cells in by_algo.items():
            n = cells["worst_case_rechecked"]["n_seeds"]
            row = " | ".join(ci(cells[c], 1) for c in COLUMNS)
            lines.append(f"| {task_name(task)} | {name(algo)} | {n} of {cells['runs']} | {row} |")
    return [*lines, ""]
