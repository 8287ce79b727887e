"""The paper's scores (§5), defined once: worst case, average case, their in- and
out-of-distribution variants, and the normalised score.

Why one module: ``EvaluationResult`` (one run), the benchmark's statistics and the report all
compute these numbers; each used to spell them out itself, so a change of convention could
reach one and not the others. Here a run's scores are *reductions of its per-point mean
returns* (the mean return over each mesh point's episodes): the worst case is their minimum, the
average case their mean. The reductions are named as pandas names them, so a single run
(``scores_of``) and a table of many runs (``run_scores``) reduce the same way, bit for bit.
Torch-free, and pandas is only used through the tables it is given.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

__all__ = [
    "REDUCTIONS",
    "SCORES",
    "SPLIT_SCORES",
    "normalization_span",
    "normalized_score",
    "normalized_std",
    "point_means",
    "run_scores",
    "scores_of",
    "split_run_scores",
]

#: a run's score -> the reduction of its per-point mean returns that gives it
REDUCTIONS = {"worst_case": "min", "average_case": "mean"}
SCORES = tuple(REDUCTIONS)
#: with a train/test split of the set: the scores over the in-distribution (``_id``, the part
#: the runs trained on) and the out-of-distribution (``_ood``) mesh points separately
SPLIT_SCORES = tuple(f"{score}_{tag}" for tag in ("id", "ood") for score in SCORES)


def scores_of(point_means: Any) -> dict[str, float]:
    """``{"worst_case", "average_case"}`` of one run from its per-point mean returns (a pandas
    Series)."""
    return {score: float(point_means.agg(how)) for score, how in REDUCTIONS.items()}


def point_means(episodes: Any, keys: Sequence[str] = ()) -> Any:
    """The mean return over each mesh point's episodes, per ``keys`` (e.g. task, algorithm,
    seed) and point: a Series indexed by ``(*keys, "point")``."""
    return episodes.groupby([*keys, "point"], sort=True)["return"].mean()


def run_scores(episodes: Any, keys: Sequence[str] = ("task", "algorithm", "seed")) -> Any:
    """One row per run (``keys``): its worst and average case over the whole mesh."""
    keys = list(keys)
    point = point_means(episodes, keys)
    table = point.groupby(level=keys).agg(list(REDUCTIONS.values()))
    return table.rename(columns={how: score for score, how in REDUCTIONS.items()}).reset_index()


def split_run_scores(episodes: Any, keys: Sequence[str] = ("task", "algorithm", "seed")) -> Any:
    """One row per run: the scores over the in-distribution and the out-of-distribution mesh
    points separately (episodes flagged ``in_distribution``, as CSV text or booleans); NaN
    where a run has no point of a part."""
    keys = list(keys)
    flag = episodes["in_distribution"].astype(str).str.lower() == "true"  # CSV or Parquet
    point = (
        episodes.assign(in_distribution=flag)
        .groupby([*keys, "point", "in_distribution"], sort=True)["return"]
        .mean()
    )
    table = point.reset_index()[keys].drop_duplicates().reset_index(drop=True)
    for value, tag in ((True, "id"), (False, "ood")):
        part = point[point.index.get_level_values("in_distribution") == value]
        names = {how: f"{score}_{tag}" for score, how in REDUCTIONS.items()}
        if len(part):
            scores = part.groupby(level=keys).agg(list(REDUCTIONS.values())).reset_index()
            table = table.merge(scores.rename(columns=names), on=keys, how="left")
        else:
            table = table.assign(**{name: np.nan for name in names.values()})
    return table


def normalized_score(v: ArrayLike, v_td3: ArrayLike, v_m2td3: ArrayLike) -> np.ndarray | np.float64:
    """``(v - v_td3) / |v_m2td3 - v_td3|``: 0 is TD3's score, 1 (or -1) is M2TD3's distance.

    >>> normalized_score(19.78, -123.64, 2322.73).round(2)  # DR's worst case on Ant (Table 4)
    np.float64(0.06)
    """
    v, v_td3 = np.asarray(v, dtype=np.float64), np.asarray(v_td3, dtype=np.float64)
    return (v - v_td3) / normalization_span(v_td3, v_m2td3)


def normalized_std(std: float, v_td3: float, v_m2td3: float) -> float:
    """A standard deviation in normalised units (the score is an affine map of the return)."""
    return float(std / normalization_span(v_td3, v_m2td3))


def normalization_span(v_td3: ArrayLike, v_m2td3: ArrayLike) -> np.ndarray | np.float64:
    """``|v_m2td3 - v_td3|``, refused (one line) where it is 0 or not finite: the normalised
    score is then undefined."""
    span = np.abs(np.asarray(v_m2td3, dtype=np.float64) - np.asarray(v_td3, dtype=np.float64))
    if np.any(span == 0):
        raise ValueError("TD3 and M2TD3 references are equal: the normalised score is undefined")
    if not np.all(np.isfinite(span)):
        raise ValueError(
            "TD3 and M2TD3 references are not finite: the normalised score is undefined"
        )
    return span
