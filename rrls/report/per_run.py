"""One row per run: did it learn the nominal task, and what did it score over the set?

Why: a table of means hides a seed that never learned, and a normalised score against such a
baseline means little. Researchers citing a result want each run's final nominal return (the
last periodic evaluation on the nominal parameters) beside its worst and average case.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from rrls.report.names import display_name
from rrls.report.stats import per_seed_scores

__all__ = ["per_run_table", "per_run_lines"]


def per_run_table(tables: dict[str, Any]) -> Any:
    """``task, algorithm, seed, steps, final_nominal_return, final_nominal_step, worst_case,
    average_case``: ``steps`` is the run's training budget (its ``result.json``; a submission's
    declared one, empty when not stated), ``final_nominal_step`` the step of the last periodic
    evaluation whose nominal return is shown."""
    import pandas as pd

    keys = ["task", "algorithm", "seed"]
    scores = per_seed_scores(tables["evaluations"])
    curves = tables.get("curves")
    if curves is not None and len(curves) and "eval_nominal_return" in curves:
        last = (
            curves.dropna(subset=["eval_nominal_return"])
            .sort_values("step")
            .groupby(keys, sort=True)
            .tail(1)[[*keys, "step", "eval_nominal_return"]]
            .rename(
                columns={
                    "step": "final_nominal_step",
                    "eval_nominal_return": "final_nominal_return",
                }
            )
        )
        scores = scores.merge(last, on=keys, how="left")
    else:
        scores = scores.assign(final_nominal_step=float("nan"), final_nominal_return=float("nan"))
    runs = tables.get("runs")
    if runs is not None and len(runs) and "steps" in runs:
        budget = runs[[*keys, "steps"]].drop_duplicates(keys)
        scores = scores.merge(budget, on=keys, how="left")
        # 0: a submission that states no budget
        scores["steps"] = pd.to_numeric(scores["steps"]).where(lambda s: s > 0).astype("Int64")
    else:
        scores = scores.assign(steps=pd.array([pd.NA] * len(scores), dtype="Int64"))
    cols = [*keys, "steps", "final_nominal_return", "final_nominal_step"]
    return scores[cols + ["worst_case", "average_case"]]


def per_run_lines(
    table: Any, order: list[str], name: Callable[[str], str] = display_name
) -> list[str]:
    """The markdown section of ``report.md``, each algorithm as ``name`` calls it."""
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
            f"| {row.task} | {name(row.algorithm)} | {row.seed} | {nominal} "
            f"| {row.worst_case:.1f} | {row.average_case:.1f} |"
        )
    return [*lines, ""]
