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
    """Alone vs in a group: equal to float32 rounding (tests/test_group.py states the tolerance;
    after a whole smoke run a few weights differ in the last bit)."""
    wa, wb = _weights(a), _weights(b)
    assert wa.keys() == wb.keys()
    for name in wa:
        np.testing.assert_allclose(wa[name], wb[name], rtol=0, atol=1e-5, err_msg=name)


@pytest.mark.e2e
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
        (["--seeds=-1"], "a seed is an integer from 0 to 4294967295, got -1"),
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


@pytest.mark.e2e
def test_packed_benchmark_gives_the_numbers_of_unpacked_runs(tmp_path):
    from rrls.benchmark.grid import make_spec
    from rrls.benchmark.pipeline import execute_group
    from rrls.benchmark.runner import benchmark

    spec = make_spec("smoke", algos="td3", seeds=2)
    alone, packed = tmp_path / "alone", tmp_path / "packed"
    assert benchmark(alone, spec, 2) == 0
    assert benchmark(packed, spec, 1, pack=2) == 0
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
    from rrls.benchmark.grid import make_spec
    from rrls.benchmark.pipeline import GroupFailed, execute_group

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


def test_no_two_runs_and_no_two_purposes_share_a_stream():
    # every generator of a run is a child of SeedSequence(seed), one per purpose: the first
    # words of every (seed, purpose) stream are distinct, numpy and torch alike; the old scheme
    # (seeds s, s+1, s+2 for init, noise, replay) gave run s's noise run s+1's init stream
    pytest.importorskip("torch")
    from rrls.agents.streams import PURPOSES, RunSeeds

    purposes = [*PURPOSES, "adversary.init", "adversary.noise", "adversary.replay"]
    numpy_words, torch_words, env_seeds = set(), set(), set()
    for seed in range(8):
        seeds = RunSeeds(seed)
        for purpose in purposes:
            words = tuple(seeds.numpy(purpose).integers(0, 2**63, 4).tolist())
            assert words not in numpy_words
            numpy_words.add(words)
            import torch

            draw = tuple(torch.randint(0, 2**62, (4,), generator=seeds.torch(purpose)).tolist())
            assert draw not in torch_words
            torch_words.add(draw)
            env_seeds.add(seeds.integer(purpose))
    assert len(env_seeds) == 8 * len(purposes)
    # the env's first reset and the warm-up draws are different streams (they were the same
    # PCG64 stream: default_rng(seed) and reset(seed=seed))
    import gymnasium as gym

    env = gym.make("InvertedPendulum-v5")
    env.reset(seed=RunSeeds(3).integer("env"))
    env_draws = env.unwrapped.np_random.random(4)
    assert not np.array_equal(env_draws, RunSeeds(3).numpy("warmup").random(4))
    assert not np.array_equal(env_draws, np.random.default_rng(3).random(4))


def test_a_runs_generators_all_come_from_its_seed(tmp_path):
    # the same seed gives the same numbers; seeds s and s+1 share none of their draws
    torch = pytest.importorskip("torch")
    from rrls.agents.algos import td3
    from rrls.agents.streams import RunSeeds

    env = td3.make_env("invertedpendulum", "2d", td3.Config(hidden=(4,)))

    def learner(seed):
        return td3.Learner(env, td3.Config(hidden=(4,)), [RunSeeds(seed)], torch.device("cpu"))

    a, b, c = learner(5), learner(5), learner(6)
    first = [p.detach().flatten() for p in a.agent.actor.parameters()]
    assert all(
        torch.equal(x, y.detach().flatten()) for x, y in zip(first, b.agent.actor.parameters())
    )
    # run 5's target-noise draws are not run 6's initialisation (nor anything of run 6)
    noise = a.agent.draw(8).flatten()
    assert not torch.equal(noise, c.agent.draw(8).flatten())
    init6 = torch.randn(8, generator=RunSeeds(6).torch("init"))
    assert not torch.equal(noise, init6)
