"""An evaluation's result: one row per (mesh point, episode), and the paper's two numbers."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from rrls.evaluation import evaldir
from rrls.evaluation.metrics import SCORES, scores_of
from rrls.uncertainty import UncertaintySet

__all__ = ["EPISODE_COLUMNS", "EvaluationResult"]

EPISODE_COLUMNS = ("point", "episode", "seed", "return", "length", "terminated", "diverged")


@dataclass
class EvaluationResult:
    """Per-episode table plus the paper's two numbers.

    ``worst_case`` is the minimum over mesh points of the mean return over that point's episodes,
    ``average_case`` the mean over points of that same per-point mean.
    """

    task: str
    uncertainty: UncertaintySet | None
    episodes: Any  # pandas.DataFrame, one row per (point, episode)
    config: dict[str, Any] = field(default_factory=dict)

    @property
    def param_names(self) -> list[str]:
        return list(self.uncertainty.names) if self.uncertainty is not None else []

    @property
    def per_point(self) -> Any:
        """One row per mesh point: its parameters and the mean/std/min return over its episodes
        (and ``in_distribution`` when the evaluation was given a split)."""
        cols = ["point", *self.param_names]
        if "in_distribution" in self.episodes:
            cols.append("in_distribution")
        grouped = self.episodes.groupby(cols, sort=True)["return"]
        table = grouped.agg(["mean", "std", "min", "count"]).reset_index()
        return table.rename(
            columns={
                "mean": "mean_return",
                "std": "std_return",
                "min": "min_return",
                "count": "episodes",
            }
        )

    @property
    def worst_case(self) -> float:
        return scores_of(self.per_point["mean_return"])["worst_case"]

    @property
    def average_case(self) -> float:
        return scores_of(self.per_point["mean_return"])["average_case"]

    @property
    def worst_point(self) -> dict[str, float]:
        """Parameters of the mesh point with the lowest mean return."""
        table = self.per_point
        row = table.loc[table["mean_return"].idxmin()]
        return {name: float(row[name]) for name in self.param_names}

    @property
    def n_diverged(self) -> int:
        return int(self.episodes["diverged"].sum())

    def split_scores(self) -> dict[str, float | int | None]:
        """Worst and average case over the in-distribution (training part) and the
        out-of-distribution (test part) mesh points separately; empty without a split."""
        if "in_distribution" not in self.episodes:
            return {}
        table = self.per_point
        out: dict[str, float | int | None] = {}
        for tag, mask in (("id", table["in_distribution"]), ("ood", ~table["in_distribution"])):
            means = table.loc[mask, "mean_return"]
            scores = scores_of(means) if len(means) else {}
            for score in SCORES:
                out[f"{score}_{tag}"] = scores.get(score)
            out[f"points_{tag}"] = int(mask.sum())
        return out

    def summary(self) -> dict[str, Any]:
        """What ``summary.json`` holds."""
        return {
            "task": self.task,
            "uncertainty": self.config.get("uncertainty"),
            "worst_case": self.worst_case,
            "average_case": self.average_case,
            "worst_point": self.worst_point,
            "points": int(self.episodes["point"].nunique()),
            "episodes_total": len(self.episodes),
            "diverged": self.n_diverged,
            **self.split_scores(),
            **{k: v for k, v in self.config.items() if k not in ("uncertainty",)},
        }

    def save(self, out_dir: str | Path) -> Path:
        """Write ``summary.json`` and ``episodes.parquet`` (``.csv`` without pyarrow) atomically."""
        return evaldir.write(out_dir, self.summary(), self.episodes)

    @classmethod
    def load(cls, out_dir: str | Path) -> EvaluationResult:
        summary, episodes = evaldir.read(out_dir)
        box = summary.get("uncertainty")
        box = UncertaintySet(**box) if box and box.get("names") else None
        config = {k: summary[k] for k in summary if k not in _DERIVED}
        config["uncertainty"] = summary.get("uncertainty")
        return cls(summary["task"], box, episodes, config)

    def __repr__(self) -> str:
        label = self.uncertainty.label if self.uncertainty is not None else f"{self.task}/nominal"
        split = self.split_scores()
        extra = (
            f", ID worst/average={_fmt(split['worst_case_id'])}/{_fmt(split['average_case_id'])}"
            f", OOD worst/average={_fmt(split['worst_case_ood'])}/"
            f"{_fmt(split['average_case_ood'])}"
            if split
            else ""
        )
        return (
            f"EvaluationResult({label}: worst_case={self.worst_case:.2f}, "
            f"average_case={self.average_case:.2f}{extra}, {len(self.episodes)} episodes)"
        )


def _fmt(value: float | None) -> str:
    return "-" if value is None else f"{value:.2f}"


_DERIVED = {
    "task",
    "uncertainty",
    "worst_case",
    "average_case",
    "worst_point",
    "points",
    "episodes_total",
    "diverged",
    *(f"{m}_{t}" for m in ("worst_case", "average_case", "points") for t in ("id", "ood")),
}
