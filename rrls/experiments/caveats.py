"""What a table must say about itself: too few seeds for an interval, a normalisation that
divides by noise. A reader who cites a cell should see its caveat beside it, not discover it.
"""

from __future__ import annotations

from typing import Any

__all__ = ["FEW", "FEW_SEEDS_NOTE", "few_seeds", "unstable_normalisation"]

FEW = "†"  # marks a cell from fewer than 3 seeds
FEW_SEEDS_NOTE = (
    f"{FEW} fewer than 3 seeds: ± is the seeds' spread and a bracketed interval is a bootstrap "
    "of at most two values, not a confidence interval; one seed shows its value alone."
)


def few_seeds(cell: dict[str, Any] | None) -> bool:
    """Whether ``cell`` (a summary cell with ``n_seeds``) rests on fewer than 3 seeds."""
    return bool(cell) and 0 < int(cell.get("n_seeds") or 0) < 3


def unstable_normalisation(summary: dict[str, Any]) -> list[str]:
    """One line per (task, criterion) whose normaliser ``|M2TD3 - TD3|`` is smaller than the two
    baselines' seed spread (or whose baselines both failed): its normalised scores divide by
    noise, so the report flags them instead of dividing silently."""
    lines = []
    for task in summary["tasks"]:
        cells = summary["results"].get(task, {})
        for criterion in ("worst_case", "average_case"):
            td3 = (cells.get("td3") or {}).get(criterion) or {}
            m2 = (cells.get("m2td3") or {}).get(criterion) or {}
            if td3.get("mean") is None or m2.get("mean") is None:
                continue
            span = abs(m2["mean"] - td3["mean"])
            spread = max(td3.get("std") or 0.0, m2.get("std") or 0.0)
            if span <= spread:
                lines.append(
                    f"- **unstable normalisation**, {task} {criterion.replace('_', ' ')}: "
                    f"|M2TD3 - TD3| = {span:.1f} is within the baselines' seed spread "
                    f"({spread:.1f}); its normalised scores divide by noise (read the raw table)"
                )
    return lines
