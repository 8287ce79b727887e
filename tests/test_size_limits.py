"""Every size a user gives is checked against a stated limit, or against this machine's memory,
before anything is allocated: one line naming it, exit 2, and no process eating the machine."""

from __future__ import annotations

import dataclasses
import time

import numpy as np
import pytest

from rrls.agents import hparams
from rrls.agents.config import TrainConfig
from rrls.cli import main
from rrls.evaluation import MLPPolicy, evaluate


def _run(argv: list[str], capsys) -> tuple[int, str]:
    try:
        code = main(argv)
    except SystemExit as stop:
        code = stop.code
    err = capsys.readouterr().err
    assert "Traceback" not in err
    return code, err


@pytest.fixture(scope="module")
def policy_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("limits") / "p.npz"
    MLPPolicy.random(4, 1, (8,), seed=0).save(path)
    return str(path)


TRAIN = ["train", "--algo", "td3", "--task", "invertedpendulum", "--steps", "300"]


@pytest.mark.parametrize(
    ("argv", "culprit"),
    [
        ([*TRAIN, "--batch-size", "1000000000"], "batch_size"),
        ([*TRAIN, "--buffer-size", "100000000000"], "buffer_size"),
        ([*TRAIN, "--hidden", "100000", "100000"], "hidden"),
        ([*TRAIN, "--hidden", *["8"] * 65], "hidden"),
        ([*TRAIN, "--threads", "100000"], "threads"),  # torch crashed (signal 11) here
        ([*TRAIN, "--workers", "100000"], "--workers"),
        ([*TRAIN, "--eval-episodes", "100000000"], "eval_episodes"),
        ([*TRAIN, "--eval-mesh", "100000"], "eval_mesh"),
        (["train", "--algo", "m2td3", "--task", "invertedpendulum", "--steps", "300",
          "--hatomega-number", "100000000"], "hatomega_number"),  # took 10 GB before
        (["train", "--algo", "rarl", "--task", "invertedpendulum", "--steps", "300",
          "--history", "100000000"], "history"),
        (["evaluate", "{p}", "--task", "invertedpendulum", "--workers", "100000"], "--workers"),
        (["evaluate", "{p}", "--task", "invertedpendulum", "--batch-size", "10000000"],
         "batch_size"),
        (["evaluate", "{p}", "--task", "invertedpendulum", "--mesh", "10000000"], "mesh"),
        (["evaluate", "{p}", "--task", "invertedpendulum", "--episodes", "1000000000"],
         "episodes"),
        (["benchmark", "--preset", "smoke", "--out", "{t}/b", "--workers", "100000",
          "--dry-run"], "--workers"),
        (["benchmark", "--preset", "smoke", "--out", "{t}/b", "--episodes", "1000000000",
          "--dry-run"], "episodes"),  # planned happily before, refused after training
        (["benchmark", "--preset", "smoke", "--out", "{t}/b", "--mesh", "10000000",
          "--dry-run"], "mesh"),
        (["benchmark", "--preset", "smoke", "--out", "{t}/b", "--seeds", "4294967296",
          "--dry-run"], "seed"),
    ],
)  # fmt: skip
def test_sizes_above_their_limit_are_refused_in_one_line(
    argv, culprit, policy_file, tmp_path, capsys
):
    argv = [a.format(p=policy_file, t=tmp_path) for a in argv]
    start = time.perf_counter()
    code, err = _run([*argv, *(["--out", str(tmp_path / "o")] if argv[0] != "benchmark" else [])],
                     capsys)  # fmt: skip
    assert code == 2, err
    assert len(err.strip().splitlines()) == 1 and culprit in err, err
    assert time.perf_counter() - start < 60  # refused, not attempted
    assert not (tmp_path / "o" / "policy.npz").exists()


def test_every_declared_limit_is_enforced():
    """Each ``hp(..., most=)`` of every built-in algorithm's Config and of TrainConfig refuses
    one more than its limit, naming the field."""
    from rrls.agents.lookup import algorithm
    from rrls.benchmark.grid import BUILT_IN

    classes = {TrainConfig} | {algorithm(name).Config for name in BUILT_IN}
    probed = 0
    for cls in classes:
        for f in dataclasses.fields(cls):
            most = f.metadata.get("most")
            if most is None:
                continue
            limit = most() if callable(most) else most
            bad = (limit + 1,) if f.name == "hidden" else limit + 1
            kwargs = {"algo": "td3", "task": "invertedpendulum"} if cls is TrainConfig else {}
            with pytest.raises(ValueError, match=f"{f.name} must be at most"):
                cls(**kwargs, **{f.name: bad})
            probed += 1
    assert probed >= 10


def test_memory_is_checked_before_the_learner_allocates(tmp_path, capsys, monkeypatch):
    # a machine of 64 MiB: the default 1e6-transition buffer for 30 000 steps (~4.7 MiB) and
    # 256-256 networks (~7 MiB with their optimiser) fit; 64 runs' of them do not
    from rrls.agents import group

    monkeypatch.setattr(hparams, "machine_memory", lambda: 64 * 2**20)
    env = type("E", (), {})()
    import gymnasium as gym

    env.observation_space = gym.spaces.Box(-1, 1, (11,))
    env.action_space = gym.spaces.Box(-1, 1, (3,))
    hyper = type("H", (), {"buffer_size": 1_000_000, "hidden": (256, 256)})()
    group.check_group_memory(hyper, env, 1, 30_000)
    with pytest.raises(MemoryError) as err:
        group.check_group_memory(hyper, env, 64, 30_000)
    assert "64 run(s)" in str(err.value) and "GiB" in str(err.value)


def test_evaluation_sizes_are_refused_by_the_library_too():
    policy = MLPPolicy.random(4, 1, (8,), seed=0)
    for kwargs, name in (
        ({"workers": 5000}, "workers"),
        ({"batch_size": 10**7}, "batch_size"),
        ({"mesh": 10**7}, "mesh"),
        ({"episodes": 10**9, "mesh": 2}, "episodes"),
    ):
        with pytest.raises(ValueError, match=name):
            evaluate(policy, "invertedpendulum", "1d", **kwargs)
    assert np.isfinite(evaluate(policy, "invertedpendulum", "1d", mesh=2, episodes=1).worst_case)
