"""``rrls train --simulator warp`` on warp's CPU device: the training loop of every run with its
envs on the twin (run k on world k), each episode begun on the run's CPU env and copied to its
world, the run's files saying what trained it, resume, and the refusals."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from rrls.twin.catalog import check_twin

TRAIN = ["train", "--task", "hopper", "--simulator", "warp", "--device", "cpu"]
TRAIN += ["--learning-starts", "30", "--checkpoint-every", "30", "--eval-every", "30"]


def test_what_the_twin_cannot_train_is_refused_saying_why():
    for args, words in (
        (("td3", "humanoidstandup", "v5"), "PGS"),
        (("td3", "reacher", "v5"), "tasks with one"),
        (("td3", "hopper", "paper"), "--physics paper is CPU only"),
    ):
        with pytest.raises(ValueError, match=words):
            check_twin(*args)
    import importlib.util

    if importlib.util.find_spec("warp") and importlib.util.find_spec("mujoco_warp"):
        for algo in ("td3", "dr", "m2td3", "sac", "sacdr", "nrmdp", "rarl"):
            check_twin(algo, "hopper", "v5")
    else:  # without the extra: the line says how to install it
        with pytest.raises(ValueError, match="needs .*warp"):
            check_twin("td3", "hopper", "v5")


def test_a_benchmark_on_the_twin_is_another_protocol_and_a_cpu_one_is_unchanged():
    from dataclasses import replace

    from rrls.benchmark.grid import PRESETS, Benchmark

    cpu = Benchmark(**PRESETS["smoke"])
    assert "simulator" not in cpu.binding_fields()  # benchmark.json files written before: the same
    twin = replace(cpu, simulator="warp")
    assert twin.binding_fields()["simulator"] == "warp"
    assert twin.fingerprints()["benchmark"] != cpu.fingerprints()["benchmark"]
    assert twin.fingerprints()["protocol"] == cpu.fingerprints()["protocol"]  # same evaluation


def test_the_paper_preset_on_the_twin_trains_humanoidstandup_on_cpu_mujoco():
    """A warp benchmark runs whole: the tasks without a twin (HumanoidStandup's PGS solver)
    train on CPU MuJoCo beside the twin's; a benchmark with no twin task at all is refused."""
    import importlib.util
    from dataclasses import replace

    from rrls.benchmark.grid import PRESETS, Benchmark, SpecError, validate
    from rrls.benchmark.runner import plan

    spec = replace(Benchmark(**PRESETS["paper"]), simulator="warp")
    assert {t: spec.simulator_for(t) for t in spec.tasks} == {
        "ant": "warp",
        "halfcheetah": "warp",
        "hopper": "warp",
        "humanoidstandup": "mujoco",
        "walker": "warp",
    }
    assert Benchmark(**PRESETS["paper"]).simulator_for("hopper") == "mujoco"
    if importlib.util.find_spec("warp") and importlib.util.find_spec("mujoco_warp"):
        validate(spec)
        with pytest.raises(SpecError, match="PGS"):
            validate(replace(spec, tasks=("humanoidstandup",)))
    text = plan(Path("bench"), spec, 250, 0, 0, "local", 10)
    assert "but humanoidstandup (no twin: CPU MuJoCo" in text
    assert "a task's algorithms share each twin step" in text
    from rrls.benchmark.gpu_estimate import describe

    on_gpu = describe(replace(spec, device="cuda"), 10)
    assert "25 groups" in on_gpu and "sharing each twin step save is not measured" in on_gpu
    assert "not measured yet" not in describe(replace(spec, device="cuda", simulator="mujoco"), 10)


def test_on_the_twin_a_tasks_algorithms_are_one_group_and_humanoidstandup_is_not():
    """``rrls benchmark --simulator warp`` packs each task's cells of one turn into one group
    (one twin step for its algorithms, ``rrls.agents.shared``); a task without a twin, RARL in
    TC-RMDP's rate-limited game and a CPU benchmark keep one cell a group."""
    from dataclasses import replace

    from rrls.benchmark.grid import PRESETS, Benchmark
    from rrls.benchmark.pipeline import groups

    spec = replace(Benchmark(**PRESETS["paper"]), simulator="warp", seeds=(0, 1, 2))
    packed = groups(spec.runs(), 2, spec)
    assert sorted(k for g in packed for k in g) == sorted(spec.runs())
    shape = [(g[0].task, len({k.algo for k in g}), len(g)) for g in packed]
    assert shape[:4] == [("ant", 5, 10), ("halfcheetah", 5, 10), ("hopper", 5, 10)] + [
        ("humanoidstandup", 1, 2)
    ]
    assert ("walker", 5, 5) in shape and ("humanoidstandup", 1, 1) in shape  # the third seeds
    cpu = groups(spec.runs(), 2, replace(spec, simulator="mujoco"))
    assert all(len({k.algo for k in g}) == 1 for g in cpu) and len(cpu) == 50
    rate_limited = replace(spec, rate_limit=0.1)  # TC-RMDP's game: RARL stays on its own
    assert all(
        {k.algo for k in g} in ({"rarl"}, {"td3", "dr", "m2td3", "nrmdp"})
        for g in groups(rate_limited.runs(), 2, rate_limited)
        if g[0].task == "hopper"
    )


pytest.importorskip("warp")
pytest.importorskip("mujoco_warp")
pytest.importorskip("torch")


@pytest.mark.warp
def test_an_episode_begins_on_the_runs_cpu_env_and_its_world_copies_it():
    from rrls.agents.twin_envs import TwinEnvs
    from rrls.envs import resolve

    make = resolve("hopper", "3d").make_env  # M2TD3's kind of env: the point comes in options
    envs = TwinEnvs(make, 2, "hopper", "3d", "cpu")
    try:
        point = {"torsomass": 5.0, "worldfriction": 0.5, "thighmass": 2.0}
        _, obs = envs.begin(1, 7, point)
        cpu = make()
        want, _ = cpu.reset(seed=7, options=point)
        assert np.array_equal(obs, want)  # the CPU env's own first observation
        mass = envs.twin.m.body_mass.numpy()[1]
        assert np.allclose(mass, cpu.unwrapped.model.body_mass, rtol=1e-6)
        _, obs0 = envs.begin(0, 3, None)
        action = np.full(3, 0.3, dtype=np.float32)
        stepped = envs.step([np.zeros(3, np.float32), action])
        after, *_ = cpu.step(action)
        assert np.abs(stepped[1][0] - after).max() < 1e-5  # float32 world vs float64 CPU
    finally:
        envs.close()


def _rrls(*args: str, env: dict | None = None) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "rrls", *args],
        capture_output=True,
        text=True,
        env={**os.environ, **(env or {})},
        timeout=900,
    )


@pytest.mark.e2e
@pytest.mark.warp
def test_rrls_train_on_the_twin_writes_runs_that_say_so_and_resume(tmp_path):
    out = tmp_path / "twin"
    done = _rrls(*TRAIN, "--algo", "dr", "--seeds", "0-1", "--steps", "60", "--out", str(out))
    assert done.returncode == 0, done.stderr[-1500:]
    for k in (0, 1):
        run = json.loads((out / f"seed{k}" / "run.json").read_text())
        assert run["simulator"] == "warp" and run["config"]["simulator"] == "warp"
        assert run["physics"] == "v5" and run["steps"] == 60
        scalars = (out / f"seed{k}" / "scalars.csv").read_text()
        assert "charts/episode_return" in scalars and "eval/" in scalars  # evaluated on CPU
    # killed after its first checkpoint, then resumed: it finishes with the steps it was given
    one = tmp_path / "one"
    argv = [*TRAIN, "--algo", "m2td3", "--seed", "0", "--steps", "60", "--out", str(one)]
    stopped = _rrls(*argv, env={"RRLS_STOP_AT": "30"})
    assert stopped.returncode != 0 or "RRLS_STOP_AT" in stopped.stderr + stopped.stdout
    assert not (one / "run.json").exists()
    resumed = _rrls(*argv, "--resume")
    assert resumed.returncode == 0, resumed.stderr[-1500:]
    assert json.loads((one / "run.json").read_text())["steps"] == 60
    # the policy evaluates where everything does, on CPU MuJoCo
    ev = _rrls("evaluate", str(one), "--mesh", "2", "--episodes", "1", "--workers", "0",
               "--out", str(tmp_path / "ev"))  # fmt: skip
    assert ev.returncode == 0, ev.stderr[-1500:]
