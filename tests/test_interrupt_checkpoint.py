"""Ctrl-C keeps the work: ``rrls train`` finishes the step Ctrl-C came in, writes a checkpoint
of it (the periodic checkpoints' writer, atomic and sealed) and prints the ``--resume`` command,
which goes on from that step to the same weights and curves as a run never interrupted, with
the default ``--checkpoint-every`` (50 000: no periodic checkpoint in these runs)."""

from __future__ import annotations

import csv
import shlex
import signal
from pathlib import Path

import numpy as np
import pytest
from conftest import interrupt_rrls, policy_arrays

torch = pytest.importorskip("torch")

from rrls.agents.run import INTERRUPTED_KEY, Run, read_checkpoint  # noqa: E402
from rrls.cli import main  # noqa: E402

#: the long end-to-end tier (.ci/run runs it after the default suite)
pytestmark = pytest.mark.e2e

ROOT = Path(__file__).resolve().parent.parent
TRAIN = ["train", "--algo", "td3", "--task", "invertedpendulum", "--steps", "400"]
TRAIN += ["--hidden", "16", "16", "--batch-size", "32", "--learning-starts", "100"]
TRAIN += ["--eval-every", "150", "--eval-episodes", "1"]


@pytest.fixture(autouse=True)
def _ctrl_c_raises():
    """Ctrl-C as a terminal gives it (a suite started in the background may ignore SIGINT)."""
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    yield
    signal.signal(signal.SIGINT, previous)


def _ctrl_c_in(monkeypatch, method: str, after: int, presses: int = 1) -> list[int]:
    """Press Ctrl-C (a real SIGINT) inside ``Run.<method>`` at the first call from step
    ``after`` on; returns the step it came in (once pressed)."""
    real = getattr(Run, method)
    pressed: list[int] = []

    def wrapped(self, *args, **kwargs):
        if not pressed and self.step >= after:
            pressed.append(self.step)
            for _ in range(presses):
                signal.raise_signal(signal.SIGINT)
        return real(self, *args, **kwargs)

    monkeypatch.setattr(Run, method, wrapped)
    return pressed


def _steps_seen(monkeypatch) -> list[int]:
    """The steps at which episodes end from now on."""
    real, seen = Run.episode_end, []

    def spy(self, *args, **kwargs):
        seen.append(self.step)
        return real(self, *args, **kwargs)

    monkeypatch.setattr(Run, "episode_end", spy)
    return seen


def _curves(run_dir: Path) -> list[tuple[str, ...]]:
    """``scalars.csv`` without its wall-clock column (steps per second)."""
    with open(run_dir / "scalars.csv", encoding="utf-8") as f:
        return [tuple(r) for r in csv.reader(f) if r[1] != "charts/steps_per_second"]


@pytest.mark.parametrize("inside", ["episode_end", "evaluate"])
def test_ctrl_c_keeps_the_step_it_came_in_and_the_printed_resume_is_bit_identical(capsys, inside):
    assert main([*TRAIN, "--out", "full"]) == 0

    capsys.readouterr()
    with pytest.MonkeyPatch.context() as patch:  # only this run is interrupted
        pressed = _ctrl_c_in(patch, inside, after=230)
        assert main([*TRAIN, "--out", "cut"]) == 130
    line = capsys.readouterr().err.strip().splitlines()[-1]
    step = pressed[0]
    state = read_checkpoint(Path("cut/checkpoint.pt"))  # sealed: a damaged file is refused
    assert int(state["step"]) == step and state[INTERRUPTED_KEY] is True
    assert step % 50_000 and step < 400  # off the periodic schedule, mid-run
    resume = shlex.join(["rrls", *TRAIN, "--out", "cut", "--resume"])
    assert line == (
        f"rrls train: interrupted; the checkpoint at the interrupted step {step:,} of 400 is "
        f"kept in cut; to go on: {resume}"
    )
    assert not (Path("cut") / "policy.npz").exists()

    with pytest.MonkeyPatch.context() as patch:
        seen = _steps_seen(patch)
        assert main(shlex.split(line.split("to go on: ")[1])[1:]) == 0  # the command as printed
    assert seen and min(seen) > step  # it went on from the interrupted step, not from 0
    full, cut = policy_arrays(Path("full")), policy_arrays(Path("cut"))
    assert full.keys() == cut.keys() and all(np.array_equal(full[k], cut[k]) for k in full)
    assert _curves(Path("cut")) == _curves(Path("full"))


def test_a_second_ctrl_c_stops_at_once_from_the_last_checkpoint(monkeypatch, capsys):
    _ctrl_c_in(monkeypatch, "episode_end", after=230, presses=2)
    assert main([*TRAIN, "--out", "run"]) == 130
    assert not Path("run/checkpoint.pt").exists()  # stopped mid-step: nothing half-written
    line = capsys.readouterr().err.strip().splitlines()[-1]
    assert line.startswith("rrls train: interrupted; no checkpoint yet")
    assert "to start again: rrls train" in line


def test_a_periodic_checkpoint_at_the_interrupted_step_is_not_written_twice(monkeypatch):
    writes = []
    real = Run.save

    def save(self, state, interrupted=False):
        writes.append((self.step, interrupted))
        real(self, state, interrupted)

    monkeypatch.setattr(Run, "save", save)
    _ctrl_c_in(monkeypatch, "episode_end", after=230)
    every = ["--checkpoint-every", "1"]  # a periodic checkpoint at every step
    assert main([*TRAIN, *every, "--out", "run"]) == 130
    assert writes[-1][1] is False and writes[-1][0] == writes[-2][0] + 1  # no extra write
    assert read_checkpoint(Path("run/checkpoint.pt"))[INTERRUPTED_KEY] is False


@pytest.mark.e2e
def test_ctrl_c_from_a_terminal_keeps_every_run_of_a_group_with_env_workers(tmp_path):
    """SIGINT to the whole process group, as a terminal sends it: the env workers ignore it
    (they would die mid-step), the runs all stop at one step, checkpointed."""
    args = ["train", "--algo", "td3", "--task", "invertedpendulum", "--steps", "200000"]
    args += ["--hidden", "16", "16", "--learning-starts", "100", "--eval-every", "0"]
    args += ["--seeds", "0-1", "--workers", "2", "--out", "run"]
    ready = tmp_path / "run" / "seed1" / "scalars.csv"  # an episode has ended: training
    done = interrupt_rrls(args, tmp_path, ready, wait=180)
    err = done.stderr
    assert done.returncode == 130, err[-2000:]
    assert "Traceback" not in err
    runs = [tmp_path / "run" / seed / "checkpoint.pt" for seed in ("seed0", "seed1")]
    steps = {int(read_checkpoint(path)["step"]) for path in runs}
    assert len(steps) == 1
    step = steps.pop()
    assert err.strip().splitlines()[-1] == (
        f"rrls train: interrupted; the checkpoints at the interrupted step {step:,} of 200,000 "
        "are kept in run/seed0, run/seed1; to go on: " + shlex.join(["rrls", *args, "--resume"])
    )


@pytest.mark.e2e
@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["ctrl-c", "scheduler"])
def test_ctrl_c_in_a_benchmark_checkpoints_the_runs_in_training_and_resumes_them_exactly(
    tmp_path, sig
):
    """A terminal's Ctrl-C to ``rrls benchmark``: its run processes ignore SIGINT and the driver
    stops them with SIGTERM, which a run in training takes as Ctrl-C. It finishes its step and
    checkpoints it (not only the last periodic checkpoint, every 100 steps in the smoke preset),
    and the same command goes on from there to the weights of a benchmark never interrupted. A
    scheduler's SIGTERM to every process of the job (driver and runs) keeps the same."""
    args = ["benchmark", "--preset", "smoke", "--algos", "td3", "--seeds", "0-0"]
    args += ["--steps", "4000", "--workers", "1"]
    run = tmp_path / "cut" / "runs" / "td3-invertedpendulum-1d-seed0"
    done = interrupt_rrls([*args, "--out", "cut"], tmp_path, run / "checkpoint.pt", 180, sig)
    assert done.returncode == 130, done.stderr[-2000:]
    assert "Traceback" not in done.stderr
    state = read_checkpoint(run / "checkpoint.pt")
    step = int(state["step"])
    assert 100 <= step < 4000
    # the step Ctrl-C came in, not the last periodic checkpoint before it; one step in 100 is
    # both, and that periodic checkpoint is the interrupted step's, not written twice (above)
    assert state[INTERRUPTED_KEY] is True or step % 100 == 0, step
    assert "1 with a checkpoint (their training goes on)" in done.stderr
    # the same command goes on from that step; a benchmark never interrupted gives the same
    assert main([*args, "--out", str(tmp_path / "cut")]) == 0
    assert main([*args, "--out", str(tmp_path / "whole")]) == 0
    cut, whole = policy_arrays(run), policy_arrays(tmp_path / "whole" / "runs" / run.name)
    assert cut.keys() == whole.keys() and all(np.array_equal(cut[k], whole[k]) for k in cut)


@pytest.mark.e2e
def test_a_schedulers_sigterm_to_train_keeps_the_step_as_ctrl_c_does(tmp_path):
    """SIGTERM (SLURM at its time limit, a preempted node) to ``rrls train`` and its env
    workers: the same checkpoint of the step it came in, the same line, exit status 130."""
    args = ["train", "--algo", "td3", "--task", "invertedpendulum", "--steps", "200000"]
    args += ["--hidden", "16", "16", "--learning-starts", "100", "--eval-every", "0"]
    args += ["--seeds", "0-1", "--workers", "2", "--out", "run"]
    ready = tmp_path / "run" / "seed1" / "scalars.csv"
    done = interrupt_rrls(args, tmp_path, ready, wait=180, sig=signal.SIGTERM)
    assert done.returncode == 130, done.stderr[-2000:]
    assert "Traceback" not in done.stderr
    states = [read_checkpoint(tmp_path / "run" / s / "checkpoint.pt") for s in ("seed0", "seed1")]
    assert all(state[INTERRUPTED_KEY] is True for state in states)
    assert len({int(state["step"]) for state in states}) == 1
    assert "to go on: " + shlex.join(["rrls", *args, "--resume"]) in done.stderr
