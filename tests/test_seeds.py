"""Several seeds in one process: ``rrls train --seeds`` and the benchmark's ``--pack``.

Packing only changes how runs are scheduled (one stacked agent for a group of seeds), never
their numbers: each run's policy and evaluation must equal those it has trained alone.
"""

from __future__ import annotations

import importlib.util
import json
import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from rrls.cli import main

pytestmark = pytest.mark.skipif(
    importlib.util.find_spec("torch") is None, reason="training needs torch (rrls[train])"
)
TINY = [
    "train",
    "--algo",
    "td3",
    "--task",
    "invertedpendulum",
    "--steps",
    "400",
    "--learning-starts",
    "100",
    "--hidden",
    "16",
    "16",
    "--batch-size",
    "16",
    "--eval-every",
    "0",
]


def _weights(path: Path) -> dict[str, np.ndarray]:
    """A policy file's arrays, without its header (which records where and when it was made)."""
    with np.load(path) as data:
        return {k: data[k] for k in data.files if k != "header"}


def _assert_same_policy(a: Path, b: Path) -> None:
    wa, wb = _weights(a), _weights(b)
    assert wa.keys() == wb.keys()
    for name in wa:
        assert np.array_equal(wa[name], wb[name]), name


def test_seeds_train_together_with_the_numbers_of_each_seed_alone(tmp_path, capsys):
    assert main([*TINY, "--seeds", "0-1"]) == 0
    out = capsys.readouterr().out
    dirs = [Path(f"runs/td3-invertedpendulum-2d-seed{s}") for s in (0, 1)]
    for d in dirs:
        assert (d / "policy.npz").exists() and f"{d}/policy.npz" in out
    assert main([*TINY, "--seed", "1", "--out", "alone"]) == 0
    _assert_same_policy(dirs[1] / "policy.npz", Path("alone/policy.npz"))
    # --out DIR: DIR/seed<S>; a finished group resumes as it is
    assert main([*TINY, "--seeds", "1", "--out", "grouped"]) == 0
    _assert_same_policy(Path("grouped/seed1/policy.npz"), Path("alone/policy.npz"))
    assert main([*TINY, "--seeds", "1", "--out", "grouped", "--resume"]) == 0
    assert "grouped/seed1/policy.npz" in capsys.readouterr().out


@pytest.mark.parametrize(
    "seeds, needle",
    [
        (["--seeds", "5-2"], "empty"),
        (["--seeds", "a-b"], "not a seed"),
        (["--seeds=-1"], "not a seed"),
        (["--seeds", "0,2,0"], "twice"),
        (["--seeds", "0-3,2"], "twice"),
        (["--seeds", ""], "empty"),
        (["--seeds", "0-1", "--seed", "3"], "exclusive"),
    ],
)
def test_bad_seeds_are_one_line_exit_2(capsys, seeds, needle):
    assert main([*TINY, *seeds]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and needle in err, err
    assert not Path("runs").exists()  # refused before anything is written


def _results(root: Path) -> dict[str, dict]:
    out = {}
    for path in sorted(root.glob("runs/*/result.json")):
        result = json.loads(path.read_text())
        result.pop("seconds")  # wall time
        returns = pd.read_parquet(path.parent / "eval" / "episodes.parquet")["return"]
        out[path.parent.name] = {**result, "returns": returns.tolist()}
    return out


def test_packed_benchmark_gives_the_numbers_of_unpacked_runs(tmp_path):
    from rrls.experiments.launch import execute_group
    from rrls.experiments.runner import benchmark
    from rrls.experiments.spec import make_spec

    spec = make_spec("smoke", algos="td3", seeds=2)
    alone, packed = tmp_path / "alone", tmp_path / "packed"
    assert benchmark(alone, spec, 2, report=False) == 0
    assert benchmark(packed, spec, 1, report=False, pack=2) == 0
    assert _results(packed) == _results(alone) and len(_results(alone)) == 2
    for run in (alone / "runs").iterdir():
        _assert_same_policy(run / "policy.npz", packed / "runs" / run.name / "policy.npz")

    # a group resumed with one run trained (not evaluated) and one not trained at all
    resumed = tmp_path / "resumed"
    seed0 = "td3-invertedpendulum-1d-seed0"
    shutil.copytree(alone / "runs" / seed0, resumed / "runs" / seed0)
    (resumed / "runs" / seed0 / "result.json").unlink()
    shutil.rmtree(resumed / "runs" / seed0 / "eval")
    keys = [("td3", "invertedpendulum", 0), ("td3", "invertedpendulum", 1)]
    execute_group(str(resumed), spec.to_json(), keys)
    assert _results(resumed) == _results(alone)


def test_a_bad_run_fails_alone_in_its_group(tmp_path):
    from rrls.experiments.launch import GroupFailed, execute_group
    from rrls.experiments.spec import make_spec

    spec = make_spec("smoke", algos="td3", seeds=2)
    broken = tmp_path / "runs" / "td3-invertedpendulum-1d-seed1"
    broken.mkdir(parents=True)
    (broken / "checkpoint.pt").write_bytes(b"not a checkpoint")
    keys = [("td3", "invertedpendulum", 0), ("td3", "invertedpendulum", 1)]
    with pytest.raises(GroupFailed, match="1 of 2"):
        execute_group(str(tmp_path), spec.to_json(), keys)
    good = tmp_path / "runs" / "td3-invertedpendulum-1d-seed0"
    assert (good / "result.json").exists() and not (good / "error.txt").exists()
    assert not (broken / "result.json").exists()
    assert "checkpoint" in (broken / "error.txt").read_text().strip().splitlines()[-1]


def test_bad_pack_is_one_line_exit_2(capsys):
    assert main(["benchmark", "--preset", "smoke", "--out", "bench", "--pack", "0"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "--pack must be >= 1" in err
