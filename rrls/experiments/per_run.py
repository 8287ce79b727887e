"""One row per run: did it learn the nominal task, and what did it score over the set?

Why: a table of means hides a seed that never learned, and a normalised score against such a
baseline means little. Researchers citing a result want each run's final nominal return (the
last periodic evaluation on the nominal parameters) beside its worst and average case.
"""

from __future__ import annotations

from typing import Any

from rrls.experiments.names import display_name
from rrls.experiments.stats import per_seed_scores

__all__ = ["per_run_table", "per_run_lines"]


def per_run_table(tables: dict[str, Any]) -> Any:
    """``task, algorithm, seed, steps, final_nominal_return, worst_case, average_case``."""
    scores = per_seed_scores(tables["evaluations"])
    curves = tables.get("curves")
    if curves is not None and len(curves) and "eval_nominal_return" in curves:
        last = (
            curves.dropna(subset=["eval_nominal_return"])
            .sort_values("step")
            .groupby(["task", "algorithm", "seed"], sort=True)
            .tail(1)[["task", "algorithm", "seed", "step", "eval_nominal_return"]]
            .rename(columns={"step": "steps", "eval_nominal_return": "final_nominal_return"})
        )
        scores = scores.merge(last, on=["task", "algorithm", "seed"], how="left")
    else:
        scores = scores.assign(steps=float("nan"), final_nominal_return=float("nan"))
    cols = ["task", "algorithm", "seed", "steps", "final_nominal_return"]
    return scores[cols + ["worst_case", "average_case"]]


def per_run_lines(table: Any, order: list[str]) -> list[str]:
    """The markdown section of ``report.md``."""
    import pandas as pd

    if not len(table):
        return []
    rank = {a: i for i, a in enumerate(order)}
    table = table.sort_values(
        ["task", "algorithm", "seed"], key=lambda c: c.map(rank) if c.name == "algorithm" else c
    )
    lines = [
        "## Per run",
        "",
        "The final nominal return is the last periodic evaluation on the nominal parameters "
        "(`tables/per_run.csv`).",
        "",
        "| task | algorithm | seed | final nominal return | worst case | average case |",
        "|---|---|---|---|---|---|",
    ]
    for row in table.itertuples(index=False):
        nominal = row.final_nominal_return
        nominal = "–" if pd.isna(nominal) else f"{nominal:.1f}"
        lines.append(
            f"| {row.task} | {display_name(row.algorithm)} | {row.seed} | {nominal} "
            f"| {row.worst_case:.1f} | {row.average_case:.1f} |"
        )
    return [*lines, ""]
