"""What the reading tests share: where the shipped results are and how a page writes a number,
and each run's mesh points and nominal curve read from its files."""

from __future__ import annotations

import json
from pathlib import Path

import pandas as pd

ROOT = Path(__file__).resolve().parent.parent
RESULTS = ROOT / "docs" / "results"


def flat(path: Path) -> str:
    """A page's text with every run of whitespace one space: a sentence wrapped anywhere."""
    return " ".join(path.read_text().split())


def spaced(value: float, fmt: str = ",.0f") -> str:
    """A number as the pages write it: thousands separated by a space (1 290)."""
    return format(value, fmt).replace(",", " ")


def results(folder: Path) -> list[dict]:
    """Each shipped run's ``result.json`` in a results folder, in run-name order."""
    return [json.loads(p.read_text()) for p in sorted(folder.glob("runs/*/result.json"))]


def mesh_points(run: Path) -> pd.DataFrame:
    """One row per mesh point of a run's final evaluation: its mean return, its episode count,
    its shortest and longest episode and whether every episode there terminated early."""
    episodes = pd.read_parquet(run / "eval" / "episodes.parquet")
    return episodes.groupby("point").agg(
        mean=("return", "mean"),
        episodes=("return", "size"),
        shortest=("length", "min"),
        longest=("length", "max"),
        fell=("terminated", "all"),
    )


def nominal_curve(run: Path) -> pd.Series:
    scalars = pd.read_csv(run / "scalars.csv")
    curve = scalars[scalars.metric == "eval/nominal_return"].sort_values("step")
    return curve.set_index("step").value
