"""What ``rrls benchmark`` checks, plans and shows before and while it trains: one-line
errors for a bad spec, the estimates and their scheduler, the order runs start in, the dry
run, the progress lines and their ETA, and the cores a few big groups evaluate on."""

from __future__ import annotations

import io
import json
import os
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import pytest

from rrls.algorithms import ALGORITHMS
from rrls.benchmark.cpu_estimate import (
    ENV_STEPS_PER_S,
    POLICY_S_PER_STEP,
    RANDOM_STEPS_PER_S,
    REPORT_S,
    STARTUP_S,
    estimate,
    format_duration,
    run_seconds,
    schedule,
    train_rate,
)
from rrls.benchmark.grid import Benchmark, RunKey, SpecError, make_spec
from rrls.benchmark.runner import Display, plan
from rrls.cli import main

REPO = Path(__file__).resolve().parents[1]
SMOKE = ["benchmark", "--preset", "smoke", "--workers", "2"]


@pytest.mark.parametrize(
    "extra, needle",
    [
        (["--algos", "td3,ppo"], "unknown algorithm 'ppo'"),
        (["--tasks", "pong"], "unknown task 'pong'"),
        (["--tasks", "invertedpendulum", "--uncertainty", "3d"], "no uncertainty set '3d'"),
        (["--seeds", "0"], "--seeds 0: a bare number is no longer a count of seeds"),
        (["--workers", "0"], "--workers must be >= 1"),
        (["--backend", "slurm"], "unknown backend"),
    ],
)
def test_bad_spec_is_one_line_exit_2(tmp_path, capsys, extra, needle):
    assert main([*SMOKE, "--out", str(tmp_path / "b"), *extra]) == 2
    err = capsys.readouterr().err
    assert needle in err and len(err.strip().splitlines()) == 1 and "Traceback" not in err
    assert not (tmp_path / "b").exists()


def test_bad_spec_from_the_command_line_has_no_traceback(tmp_path):
    proc = subprocess.run(
        [sys.executable, "-m", "rrls", "benchmark", "--out", str(tmp_path), "--seeds", "0"],
        cwd=REPO,
        capture_output=True,
        text=True,
        env={**os.environ, "PYTHONPATH": str(REPO)},
    )
    assert proc.returncode == 2 and proc.stderr.count("\n") == 1 and "Traceback" not in proc.stderr


def alone(spec, key):
    """``spec``'s grid reduced to one of its runs."""
    return replace(spec, algos=(key.algo,), tasks=(key.task,), seeds=(key.seed,))


def max_run(spec):
    """The longest run of ``spec``'s grid, each estimated alone."""
    return max(estimate(alone(spec, k), 1)["cpu_s"] for k in spec.runs())


def test_the_estimates_queue_is_the_schedulers():
    # runs start in the grid's order, each on the first worker free
    assert schedule([4.0, 4.0, 4.0], 2) == 8.0  # a second round leaves a worker idle
    assert schedule([1.0, 1.0, 6.0], 2) == 7.0  # the long run starts once the first ends
    assert schedule([6.0, 1.0, 1.0], 2) == 6.0
    assert schedule([3.0] * 15, 2) == 24.0 and schedule([3.0] * 15, 100) == 3.0
    assert schedule([], 4) == 0.0 and schedule([5.0], 0) == 5.0


def test_paper_preset_is_the_protocol_and_prints_an_estimate(tmp_path):
    spec = make_spec("paper")
    assert spec.algos == ("td3", "dr", "rarl", "nrmdp", "m2td3")
    assert spec.tasks == ("ant", "halfcheetah", "hopper", "humanoidstandup", "walker")
    assert (spec.uncertainty, len(spec.seeds), spec.steps) == ("3d", 10, 5_000_000)
    assert (spec.mesh, spec.episodes, spec.dynamic_episodes) == (10, 5, 10)
    assert spec.learning_rate is None and spec.hidden == (256, 256)  # the paper's 3e-4
    assert (spec.endpoint, spec.learning_starts) == (False, None)  # np.arange; own warm-ups
    assert [spec.warmup(a) for a in spec.algos] == [25_000] * 4 + [100_000]  # M2TD3's authors'
    est = estimate(spec, jobs=2)
    # 250 runs of unequal length on 2 workers: no sooner than half the compute, and within the
    # last run of it; then the report
    assert est["runs"] == 250 and est["cpu_s"] / 2 + REPORT_S <= est["wall_s"]
    assert est["wall_s"] <= est["cpu_s"] / 2 + REPORT_S + max_run(spec)
    # each run: the start-up, its random warm-up, then its learning steps at its algorithm's
    # calibrated single-thread rate (256-256: the calibration's size)
    warmups = [spec.warmup(a) for a in spec.algos]
    rates = [ALGORITHMS[a].cpu_steps_per_s for a in spec.algos]  # each row's measured rate
    learning = 50 * sum((5e6 - w) / r for w, r in zip(warmups, rates))
    warmup = 50 * sum(warmups) / RANDOM_STEPS_PER_S
    assert est["train_s"] == pytest.approx(learning + warmup + 250 * STARTUP_S)
    # with a worker per run, the wall time is the longest run's: RARL, which trains two players
    assert estimate(spec, jobs=250)["wall_s"] == pytest.approx(max_run(spec) + REPORT_S)
    longest = max(spec.runs(), key=lambda k: estimate(alone(spec, k), 1)["cpu_s"])
    assert longest.algo == "rarl"
    text = plan(tmp_path, spec, 250, 0, 2, "local")
    assert "250 runs" in text and "estimate" in text and "days" in text
    # explicit options override the preset
    assert make_spec("paper", tasks="hopper", seeds=3, steps=1000).seeds == (0, 1, 2)
    assert make_spec("quick", steps=1000).learning_starts == 200


def test_a_resumed_benchmark_estimates_what_is_left_from_the_runs_steps(tmp_path):
    from rrls.benchmark.pipeline import ProgressFile, run_dir

    spec = make_spec("hopper")
    td3, dr, rarl = (RunKey(a, "hopper", 0) for a in ("td3", "dr", "rarl"))
    whole = estimate(spec, 2)
    # a run trained through its budget costs its start-up and its final evaluation only; one
    # half-trained, half its learning steps more; the others as in the whole grid
    through = estimate(spec, 1, runs=[td3], trained={td3: spec.steps})
    final = 10**3 * 5 * 1000 * (1 / ENV_STEPS_PER_S["hopper"] + POLICY_S_PER_STEP)  # mesh x 5
    assert through["train_s"] == pytest.approx(STARTUP_S)
    assert through["eval_s"] == pytest.approx(final)
    half = estimate(spec, 1, runs=[rarl], trained={rarl: 350_000})["train_s"] - STARTUP_S
    fresh = estimate(spec, 1, runs=[rarl])["train_s"] - STARTUP_S
    assert half == pytest.approx(350_000 / ALGORITHMS["rarl"].cpu_steps_per_s)
    warmup = 25_000 / RANDOM_STEPS_PER_S  # random steps, no update
    assert fresh == pytest.approx(warmup + 325_000 / ALGORITHMS["rarl"].cpu_steps_per_s + half)
    # the plan reads each run's last progress.json: a fresh benchmark has no line for it
    assert "runs left" not in plan(tmp_path, spec, 25, 0, 2, "local", left=spec.runs())
    for key, phase, step in ((td3, "evaluate", 700_000), (dr, "train", 183_405)):
        run_dir(tmp_path, spec, key).mkdir(parents=True)
        ProgressFile(run_dir(tmp_path, spec, key) / "progress.json", spec.steps).write(phase, step)
    left = estimate(spec, 2, runs=spec.runs(), trained={td3: 700_000, dr: 183_405})
    text = plan(tmp_path, spec, 25, 0, 2, "local", left=spec.runs())
    assert "for the 25 runs left (2 part-trained, counted from their last step): " in text
    assert f"{format_duration(left['cpu_s'])}, about {format_duration(left['wall_s'])}" in text
    saved = (675_000 + 183_405 - 25_000) / ALGORITHMS["td3"].cpu_steps_per_s  # their learning
    assert whole["cpu_s"] - left["cpu_s"] > saved


class _Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


@pytest.mark.parametrize("stream_type", [io.StringIO, _Terminal])
def test_progress_shows_counts_running_runs_and_failures(tmp_path, stream_type):
    spec = make_spec("smoke", algos="td3,dr,m2td3")
    keys = spec.runs()
    run = tmp_path / "runs" / keys[0].name(spec.uncertainty)
    run.mkdir(parents=True)
    (run / "progress.json").write_text(
        json.dumps({"phase": "train", "step": 150, "total": 300, "sps": 50.0})
    )
    stream = stream_type()
    display = Display(tmp_path, spec, keys, done_before=0, slots=2, stream=stream, interval=0)
    display.event(keys[0], "running", "")
    display.event(keys[1], "running", "")
    display.tick()
    display.event(keys[1], "failed", "ValueError: boom")
    display.close()
    text = stream.getvalue()
    assert "td3-invertedpendulum-1d-seed0" in text and "150/300" in text and "50 steps/s" in text
    assert "ETA 3 s" in text  # (300 - 150) / 50
    assert "FAILED dr-invertedpendulum-1d-seed0: ValueError: boom" in text
    if stream_type is io.StringIO:  # logs: plain lines with the counts
        assert "0/3 done, 2 running, 0 failed, 1 pending" in text
    else:
        assert "pending 1 running 2 done 0 failed 0" in text


def test_a_runs_steps_per_second_is_averaged_over_time_not_writes(tmp_path, monkeypatch):
    # a run writes its progress at each episode's end; a few seconds' slowdown on a shared
    # machine must not swing the display's ETA, while a lasting change of speed shows
    from rrls.benchmark import pipeline

    clock = [0.0]
    monkeypatch.setattr(pipeline.time, "monotonic", lambda: clock[0])
    progress = pipeline.ProgressFile(tmp_path / "progress.json", 1_000_000)

    def advance(seconds: float, sps: float, writes: int) -> float:
        for _ in range(writes):
            clock[0] += seconds / writes
            advance.step += round(sps * seconds / writes)
            progress.write("train", advance.step)
        return json.loads((tmp_path / "progress.json").read_text())["sps"]

    advance.step = 0
    assert advance(600, 100.0, 60) == pytest.approx(100.0)  # steady: the rate itself
    blip = advance(2, 10.0, 2)  # two short episodes at a tenth of the speed
    assert 98.0 < blip < 100.0
    assert advance(600, 50.0, 20) == pytest.approx(50.0, rel=0.01)  # ten minutes later: 50


def test_the_eta_is_the_estimate_of_what_is_left_at_the_speed_the_runs_show(tmp_path):
    from rrls.benchmark.pipeline import run_dir

    spec = make_spec("hopper")
    td3, dr, rarl, nrmdp = spec.runs()[:4]
    steps = {td3: 300_000, dr: 100_000, rarl: 20_000}  # RARL still in its random warm-up
    speed = {td3: 0.5, dr: 0.25}  # of the estimate's rate: a busy machine
    for key, step in steps.items():
        run = run_dir(tmp_path, spec, key)
        run.mkdir(parents=True)
        rate = speed[key] * train_rate(spec, key.algo) if key in speed else 2_000.0
        progress = {"phase": "train", "step": step, "total": spec.steps, "sps": rate, "pid": 1}
        (run / "progress.json").write_text(json.dumps(progress))
    display = Display(tmp_path, spec, [td3, dr, rarl, nrmdp], 0, slots=2, stream=io.StringIO())
    assert display.eta() == "?"  # nothing running, nothing finished: no speed to go by
    for key in (td3, dr, rarl):
        display.event(key, "running", "")
    # each run from its step, its training at the median speed of the learning runs (0.375: a
    # warm-up's steps/s is no learning speed), the running runs first, on 2 slots
    left = [run_seconds(spec, key, steps.get(key, 0)) for key in (td3, dr, rarl, nrmdp)]
    assert display.eta() == format_duration(schedule([t / 0.375 + e for t, e in left], 2))
    assert display.eta() != format_duration(schedule([t / 0.5 + e for t, e in left], 2))


def test_benchmark_rate_limit_is_rarls_alone_and_checked():
    spec = make_spec("smoke", rate_limit=0.05)
    assert spec.hyperparameters("rarl")["rate_limit"] == 0.05
    assert "rate_limit" not in spec.hyperparameters("td3")
    assert make_spec("smoke").hyperparameters("rarl").get("rate_limit") is None
    with pytest.raises(SpecError, match="--rate-limit must be a finite number > 0"):
        make_spec("smoke", rate_limit=-1.0)
    with pytest.raises(SpecError, match="add rarl to --algos"):
        make_spec("smoke", algos="td3", rate_limit=0.1)
    # TC-RMDP's game by default, its protagonist variants, rrls's earlier game for old files
    spec = make_spec("smoke", rate_limit=0.05, observe="stacked")
    assert spec.hyperparameters("rarl")["rate_game"] == "tc"
    assert spec.hyperparameters("rarl")["observe"] == "stacked"
    with pytest.raises(SpecError, match="--observe stacked is a protagonist of TC-RMDP's game"):
        make_spec("smoke", observe="stacked")
    old = make_spec("smoke", rate_limit=0.05).flat_json()  # benchmark.json as it was then
    del old["rate_game"], old["observe"]
    assert Benchmark.from_json(old).rate_game == "target"
    assert Benchmark.from_json({**old, "rate_limit": None}).rate_game == "tc"


def test_benchmark_split_is_canonical_and_refuses_interpolation():
    assert make_spec("smoke", split="extrapolation").split == "extrapolation:0.5"
    fields = make_spec("smoke", split="extrapolation:0.3").binding_fields()
    assert fields["split"] == "extrapolation:0.3"
    assert make_spec("smoke").protocol.plan("invertedpendulum").in_distribution is None
    protocol = make_spec("smoke", split="extrapolation").protocol.replace(mesh=5)
    plan = protocol.plan("invertedpendulum")
    assert plan.in_distribution.any() and not plan.in_distribution.all()  # in and out of it
    with pytest.raises(SpecError, match="interpolation's training part is not a box"):
        make_spec("smoke", split="interpolation")
    with pytest.raises(SpecError, match="kind must be one of interpolation, extrapolation"):
        make_spec("smoke", split="shell")
    with pytest.raises(SpecError, match="fraction of each axis"):
        make_spec("smoke", split="extrapolation:2")


def test_a_benchmark_runs_every_algorithms_first_seed_first():
    from rrls.benchmark.pipeline import groups

    spec = make_spec("smoke", seeds=3)
    alone = [(k.algo, k.seed) for g in groups(spec.runs(), 1) for k in g]
    assert alone[:5] == [(a, 0) for a in spec.algos] and alone[5] == (spec.algos[0], 1)
    packed = groups(spec.runs(), 2)
    assert [len(g) for g in packed] == [2] * 5 + [1] * 5
    assert all(len({k.algo for k in g}) == 1 for g in packed)  # a group is one cell
    assert sorted(k for g in packed for k in g) == sorted(spec.runs())


def test_a_dry_run_prints_the_plan_and_writes_nothing(tmp_path, capsys):
    out = tmp_path / "bench"
    assert main(["benchmark", "--preset", "hopper-200k", "--out", str(out), "--dry-run"]) == 0
    text = capsys.readouterr().out
    assert not out.exists()  # nothing written, nothing trained
    assert "15 runs (0 finished, 15 to run)" in text and "estimate" in text
    order = [line.split(". ", 1)[1] for line in text.splitlines() if line.strip()[:1].isdigit()]
    assert order[:2] == ["td3-hopper-3d-seed0", "dr-hopper-3d-seed0"] and len(order) == 15
    assert "report/" in text and "dry run: nothing written" in text


def test_a_few_big_groups_evaluate_on_the_cores_the_others_leave(monkeypatch):
    """A GPU benchmark's few groups (a task's algorithms on one twin) evaluate their runs on
    their share of the machine's cores; a CPU benchmark's run per core keeps one each."""
    import rrls._proc
    from rrls.benchmark.backends import eval_share

    monkeypatch.setattr(rrls._proc, "cores", lambda: 16)
    assert eval_share(groups=5, jobs=16) == 3  # the paper's 5 twin tasks' groups
    assert eval_share(groups=250, jobs=16) == 1 and eval_share(groups=5, jobs=1) == 16
    monkeypatch.setattr(rrls._proc, "cores", lambda: 2)
    assert eval_share(groups=1, jobs=2) == 2 and eval_share(groups=30, jobs=2) == 1
