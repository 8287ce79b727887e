"""The readings the results pages write in prose ("Reading it honestly", "What the table says"),
each checked against the shipped per-episode and per-run data it summarises."""

from __future__ import annotations

import sys
from pathlib import Path

import pandas as pd

ROOT = Path(__file__).resolve().parent.parent
RESULTS = ROOT / "docs" / "results"
sys.path.insert(0, str(ROOT / "benchmarks"))

import results_page  # noqa: E402


def _flat(path: Path) -> str:
    return " ".join(path.read_text().split())


def _points(run: Path) -> pd.DataFrame:
    """One row per mesh point of a run's final evaluation: its mean return, its shortest
    episode and whether every episode there terminated early."""
    episodes = pd.read_parquet(run / "eval" / "episodes.parquet")
    return episodes.groupby("point").agg(
        mean=("return", "mean"), shortest=("length", "min"), fell=("terminated", "all")
    )


def test_the_hopper_reading_of_where_the_agents_hop():
    folder = RESULTS / "hopper"
    text = _flat(folder / "README.md")
    hopping, falls = {}, []
    for run in sorted((folder / "runs").iterdir()):
        points = _points(run)
        hopping[run.name] = int(((points["mean"] >= 2000) & (points.shortest >= 1000)).sum())
        falls.append(bool(points.loc[points["mean"].idxmin(), "fell"]))
    assert len(hopping) == 15 and all(falls)  # "every run's worst mesh point is a fall"
    dr = [v for k, v in hopping.items() if k.startswith("dr-")]
    assert f"is at most {max(hopping.values())} of the 1 000 points in any run" in text
    assert max(hopping.values()) == max(dr)  # DR holds the most
    assert f"(DR: {min(dr)} to {max(dr)} on every seed;" in text
    none = sum(v == 0 for v in hopping.values())
    assert f"{none} of the 15 runs have none)" in text
    # "every DR seed lies above every TD3 seed, yet with 3 seeds their intervals still overlap"
    avg = {a: v["average_case"] for a, v in results_page.per_seed(folder).items()}
    assert min(avg["dr"]) > max(avg["td3"])
    low, _ = results_page.t_interval(avg["dr"])
    assert low < results_page.t_interval(avg["td3"])[1]
    assert "every DR seed lies above every TD3 seed, yet with 3 seeds" in text


def _provenance(run: Path) -> tuple[str, str, str]:
    import json

    info = json.loads((run / "run.json").read_text())["provenance"]
    return info["commit"][:7], info["machine"]["cpu"], info["machine"]["simd"]


def test_the_hopper_page_names_each_runs_commit_and_cpu():
    # "TD3, DR and NR-MDP ... AMD EPYC ... X86_V4 ... at rrls commit d2fabcd; all three M2TD3
    # seeds and RARL seed 0 retrained on a 2-core AMD EPYC with AVX2 only (X86_V3) at rrls
    # commit d65188c, RARL seeds 1 and 2 on a 2-core Intel Xeon with AVX-512 (X86_V4) at e0436bc"
    folder = RESULTS / "hopper"
    text = _flat(folder / "README.md")
    runs = {run.name: _provenance(run) for run in (folder / "runs").iterdir()}
    for name, (commit, cpu, simd) in runs.items():
        algo, seed = name.split("-")[0], int(name[-1])
        if algo in ("td3", "dr", "nrmdp"):
            assert (commit, cpu, simd) == ("d2fabcd", "AMD EPYC", "X86_V4"), name
        elif algo == "m2td3" or seed == 0:
            assert (commit, cpu, simd) == ("d65188c", "AMD EPYC", "X86_V3"), name
        else:
            assert commit == "e0436bc" and "Xeon" in cpu and simd == "X86_V4", name
    assert "all three M2TD3 seeds and RARL seed 0 retrained on" in text
    assert "M2TD3 (all three seeds) and RARL seed 0 at `d65188c`" in text
