"""What a table must say about itself: too few seeds for an interval, a normalisation that
divides by noise. A reader who cites a cell should see its caveat beside it, not discover it.
"""

from __future__ import annotations

from typing import Any

from rrls.algorithms import normalisers
from rrls.report.names import normaliser_names

__all__ = [
    "BUDGET",
    "BUDGET_NOTE",
    "BUDGET_TEX",
    "BUDGET_TEX_MARK",
    "budget_differs",
    "FEW",
    "FEW_SEEDS_NOTE",
    "FEW_SEEDS_TEX",
    "UNSTABLE",
    "UNSTABLE_NOTE",
    "UNSTABLE_TEX",
    "check_normaliser",
    "few_seeds",
    "is_unstable",
    "unstable_normalisation",
]

FEW = "†"  # marks a cell from fewer than 3 seeds
FEW_SEEDS_NOTE = (
    f"{FEW} fewer than 3 seeds: ± is the seeds' spread and a bracketed interval from two values "
    "is not to be trusted; one seed shows its value alone."
)
FEW_SEEDS_TEX = (
    "$^{\\dagger}$ fewer than 3 seeds: not a confidence interval (one seed: its value alone)."
)
UNSTABLE = "§"  # marks a normalised cell whose normaliser is within the baselines' noise
#: the normaliser as a reader sees it: the table's two anchors (``normalisers``) by display name,
#: ``|one - zero|``, in LaTeX ``|v_one - v_zero|``
_ZERO, _ONE = normaliser_names()
_SPAN = f"|{_ONE} - {_ZERO}|"
_TEX_SPAN = "$|v_{\\mathrm{" + _ONE + "}} - v_{\\mathrm{" + _ZERO + "}}|$"
UNSTABLE_NOTE = (
    f"{UNSTABLE} unstable normalisation: {_SPAN} on this task is within the baselines' "
    "seed spread (or both failed alike), so the normalised score divides by noise; read the raw "
    "table."
)
UNSTABLE_TEX = (
    "$^{\\S}$ unstable normalisation: "
    + _TEX_SPAN
    + " within the baselines' seed spread; read the raw table."
)
#: a normaliser under this fraction of the baselines' magnitude means both failed alike
RELATIVE_SPAN = 0.05


def few_seeds(cell: dict[str, Any] | None) -> bool:
    """Whether ``cell`` (a summary cell with ``n_seeds``) rests on fewer than 3 seeds."""
    return bool(cell) and 0 < int(cell.get("n_seeds") or 0) < 3


def check_normaliser(zero: float, zero_std: float, one: float, one_std: float) -> str | None:
    """Why ``|one - zero|`` (the seed means of the normalised score's anchors,
    ``rrls.algorithms.normalisers``) cannot normalise, or None: within the baselines' seed spread
    (the larger std), or under ``RELATIVE_SPAN`` of their magnitude."""
    span = abs(one - zero)
    spread = max(zero_std or 0.0, one_std or 0.0)
    if span <= spread:
        return f"{_SPAN} = {span:.1f} is within the baselines' seed spread ({spread:.1f})"
    scale = max(abs(zero), abs(one))
    if span < RELATIVE_SPAN * scale:
        return (
            f"{_SPAN} = {span:.1f} is under {RELATIVE_SPAN:.0%} of the baselines' "
            f"scores ({scale:.1f})"
        )
    return None


def is_unstable(summary: dict[str, Any], task: str, metric: str) -> bool:
    """Whether ``summary`` flagged the normalisation of ``task``'s ``metric``."""
    return any(u["task"] == task and u["metric"] == metric for u in summary.get("unstable") or [])


def unstable_normalisation(summary: dict[str, Any]) -> list[str]:
    """One line per (task, criterion) whose normaliser (the anchors' span) divides by noise
    (``check_normaliser``): the report flags it instead of dividing silently. Reads the
    summary's ``unstable`` entries, else checks the benchmark's own cells of the two anchors."""
    entries = summary.get("unstable")
    if entries is None:
        entries = []
        zero_algo, one_algo = normalisers()
        for task in summary["tasks"]:
            cells = summary["results"].get(task, {})
            for criterion in ("worst_case", "average_case"):
                zero = (cells.get(zero_algo) or {}).get(criterion) or {}
                one = (cells.get(one_algo) or {}).get(criterion) or {}
                if zero.get("mean") is None or one.get("mean") is None:
                    continue
                reason = check_normaliser(
                    zero["mean"], zero.get("std"), one["mean"], one.get("std")
                )
                if reason:
                    entries.append({"task": task, "metric": criterion, "reason": reason})
    return [
        f"- {UNSTABLE} **unstable normalisation**, {e['task']} {e['metric'].replace('_', ' ')}: "
        f"{e['reason']}; its normalised scores divide by noise (read the raw table)"
        for e in entries
    ]


BUDGET = "‡"  # marks a row trained with another budget than the benchmark's runs
BUDGET_TEX_MARK = "$^{\\ddagger}$"  # the mark in LaTeX (a row name, a caption)
BUDGET_NOTE = (
    f"{BUDGET} trained with another budget than this benchmark's runs, or a budget not stated "
    "(see Budgets): not a like-for-like comparison."
)


BUDGET_TEX = (
    "$^{\\ddagger}$ trained with another budget than this benchmark's runs, or a budget not "
    "stated: not a like-for-like comparison."
)


def budget_differs(summary: dict[str, Any], algo: str, source: str = "results") -> bool:
    """Whether a row's training budget is not the benchmark's: a trained run of ``algo`` with
    other steps, a submitted one stating other steps (or none), or, for the reference's rows
    (``source`` ``reference_results``), the reference's steps (or none). Without a benchmark
    budget only a submitted run stating one differs."""
    steps = (summary.get("benchmark") or {}).get("steps")
    if source != "results":
        ref = summary.get("reference") or {}
        return steps is not None and ref.get("steps") != steps
    runs = [r for r in summary.get("submitted") or [] if r["algorithm"] == algo]
    trained = (summary.get("run_steps") or {}).get(algo) or []
    return any(r.get("steps") != steps for r in runs) or (
        steps is not None and any(s != steps for s in trained)
    )
