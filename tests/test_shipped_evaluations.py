"""The shipped references' numbers come back on this CPU: each shipped run's worst point is
evaluated again from its ``policy.npz`` under its benchmark's protocol, and its episodes equal
the shipped rows bit for bit (the worst case is their mean); in the long tier, the rechecked
worst point's fresh episodes too. The runs were evaluated on other machines (``run.json``'s
``provenance``), and ``.ci/run`` repeats these with other kernels: an evaluation that depended
on a CPU's kernels would fail here, not in a reader's hands."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from rrls.benchmark import benchfile
from rrls.evaluation import engine
from rrls.evaluation.lanes import Rollouts
from rrls.evaluation.prepared import prepare
from rrls.evaluation.recheck import recheck_seeds

RESULTS = Path(__file__).resolve().parent.parent / "docs" / "results"


def _runs() -> list[Path]:
    return sorted(RESULTS.glob("*/runs/*/eval/episodes.parquet"))


def _ids() -> list[str]:
    return [f"{p.parents[3].name}/{p.parents[1].name}" for p in _runs()]


def _again(run: Path, points: np.ndarray, seeds=None) -> np.ndarray:
    """Returns of the run's policy at mesh ``points`` (its own episode seeds, or ``seeds``)."""
    protocol = benchfile.read_spec(run.parents[1]).protocol
    task = json.loads((run / "result.json").read_text())["task"]
    spec = Rollouts.from_plan(protocol.plan(task), protocol)
    sub = replace(
        spec, points=spec.points[points], seeds=spec.seeds[points] if seeds is None else seeds
    )
    return engine.run(sub, prepare(str(run / "policy.npz"), task, protocol), workers=1)["return"]


def test_every_results_folder_with_runs_is_checked():
    folders = {p.parents[3].name for p in _runs()}
    assert {"halfcheetah", "hopper", "hopper-200k"} <= folders


@pytest.mark.exactness
@pytest.mark.parametrize("episodes", _runs(), ids=_ids())
def test_a_shipped_worst_point_is_the_same_bits_here(episodes: Path):
    run = episodes.parents[1]
    shipped = pd.read_parquet(episodes).sort_values(["point", "episode"])
    means = shipped.groupby("point")["return"].mean()
    worst = int(means.idxmin())
    rows = shipped[shipped["point"] == worst]["return"].to_numpy()
    again = _again(run, np.array([worst]))
    assert np.array_equal(again, rows), f"{run.name}: point {worst} differs on this CPU"
    result = json.loads((run / "result.json").read_text())
    assert float(means.min()) == result["worst_case"]  # that point's mean is the worst case


@pytest.mark.e2e
@pytest.mark.exactness
@pytest.mark.parametrize("episodes", _runs(), ids=_ids())
def test_a_shipped_rechecked_worst_point_is_the_same_bits_here(episodes: Path):
    run = episodes.parents[1]
    result = json.loads((run / "result.json").read_text())
    if "recheck" not in result:
        pytest.skip(f"{run.name} has no rechecked worst case")
    recheck = result["recheck"]
    lowest = int(np.argmin(recheck["fresh_means"]))
    point = recheck["points"][lowest]
    seed = benchfile.read_spec(run.parents[1]).protocol.seed
    seeds = recheck_seeds(seed, np.array([point]), recheck["episodes"])
    fresh = float(_again(run, np.array([point]), seeds).reshape(1, -1).mean(axis=1)[0])
    assert fresh == recheck["fresh_means"][lowest] == result["worst_case_rechecked"]
