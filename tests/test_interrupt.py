"""Ctrl-C anywhere: one line that says what was kept and the exact command that goes on, exit
status 130, no traceback and no leaked-resource warning (the commands run as a terminal runs
them: SIGINT to the whole process group)."""

from __future__ import annotations

import os
import signal
import subprocess
from pathlib import Path

import pytest
from conftest import interrupt_rrls

ROOT = Path(__file__).resolve().parent.parent
POLICY = "import numpy as np\n\ndef zeros(obs):\n    return np.zeros((len(obs), 3))\n"


def _check(done: subprocess.CompletedProcess, line: str) -> None:
    assert done.returncode == 130, done.stderr[-2000:]
    assert "Traceback" not in done.stderr and "leaked" not in done.stderr
    assert done.stderr.strip().splitlines()[-1] == line


def _chunks(out: Path) -> int:
    return len(list((out / "chunks").glob("[0-9]*.npz")))


@pytest.mark.e2e
def test_ctrl_c_in_train_says_what_was_kept_and_how_to_resume(tmp_path):
    pytest.importorskip("torch")
    from rrls.agents.run import read_checkpoint

    args = ["train", "--algo", "td3", "--task", "invertedpendulum", "--steps", "200000"]
    args += ["--learning-starts", "100", "--checkpoint-every", "200", "--out", "run"]
    done = interrupt_rrls(args, tmp_path, tmp_path / "run" / "checkpoint.pt")
    state = read_checkpoint(tmp_path / "run" / "checkpoint.pt")  # what is on disk
    step = int(state["step"])
    assert step >= 200 and state["interrupted"]  # written at Ctrl-C, at the step it came in
    _check(
        done,
        f"rrls train: interrupted; the checkpoint at the interrupted step {step:,} of 200,000 is "
        "kept in run; to go on: rrls " + " ".join(args) + " --resume",
    )


@pytest.mark.e2e
def test_ctrl_c_in_evaluate_keeps_finished_points_and_names_the_same_command(tmp_path):
    (tmp_path / "hop.py").write_text(POLICY)
    args = ["evaluate", "hop:zeros", "--task", "hopper", "--uncertainty", "3d", "--mesh", "12"]
    args += ["--episodes", "3", "--workers", "2", "--out", "ev"]
    done = interrupt_rrls(args, tmp_path, tmp_path / "ev")
    # 12**3 points x 3 episodes: 5 184 episodes, 103 chunks of 50 and one of 34
    saved = [int(p.stem) for p in (tmp_path / "ev" / "chunks").glob("[0-9]*.npz")]
    n, kept = len(saved), sum(34 if c == 103 else 50 for c in saved)
    _check(
        done,
        f"rrls evaluate: interrupted; {kept:,} of 5,184 episodes ({n} of 104 chunks) kept in ev; "
        "to go on: rrls " + " ".join(args),
    )


# -- in this process: the step that writes raises KeyboardInterrupt, the line matches the disk --
@pytest.fixture
def stop_after_chunks(monkeypatch):
    """Ctrl-C right after the n-th chunk an evaluation saves (0: before the first); returns
    the count of chunks saved since."""
    from rrls.evaluation import engine

    real = engine.save_chunk

    def arm(n: int) -> list:
        saved: list[int] = []

        def save(*args, **kwargs):
            if len(saved) == n:
                raise KeyboardInterrupt
            real(*args, **kwargs)
            saved.append(args[1])

        monkeypatch.setattr(engine, "save_chunk", save)
        return saved

    return arm


def _ctrl_c(*args, **kwargs):
    raise KeyboardInterrupt


def _line(capsys) -> str:
    return capsys.readouterr().err.strip().splitlines()[-1]


def _policy(path: Path, obs: int, act: int, **metadata) -> str:
    from rrls.evaluation import MLPPolicy

    policy = MLPPolicy.random(obs, act, (8,), seed=0)
    policy.metadata.update(metadata)
    return str(policy.save(path))


@pytest.mark.e2e
def test_ctrl_c_in_evaluate_names_the_chunks_kept_and_the_same_command_resumes_them(
    tmp_path, capsys, monkeypatch, stop_after_chunks
):
    from rrls.cli import main
    from rrls.evaluation import engine

    monkeypatch.chdir(tmp_path)
    _policy(tmp_path / "p.npz", 11, 3)
    argv = ["evaluate", "p.npz", "--task", "hopper", "--uncertainty", "1d", "--mesh", "10"]
    argv += ["--episodes", "20", "--workers", "0", "--out", "ev"]
    stop_after_chunks(2)
    assert main(argv) == 130
    assert _chunks(tmp_path / "ev") == 2  # 10 points x 20 episodes: 4 chunks of 50
    assert _line(capsys) == (
        "rrls evaluate: interrupted; 100 of 200 episodes (2 of 4 chunks) kept in ev; to go on: "
        "rrls " + " ".join(argv)
    )
    saved = stop_after_chunks(99)  # the printed command goes on: only the 2 chunks left run
    assert main(argv) == 0 and len(saved) == 2 and (tmp_path / "ev" / "summary.json").exists()
    monkeypatch.setattr(engine, "run", _ctrl_c)
    assert main(argv) == 130  # interrupted once complete: it says so
    assert _line(capsys).startswith(
        "rrls evaluate: interrupted; the evaluation is complete in ev (summary.json written);"
    )


_MID_FORK = {"armed": False, "registered": False}


def _ctrl_c_in_the_child() -> None:
    if _MID_FORK["armed"]:  # Ctrl-C landing in a worker while it is being forked
        os.kill(os.getpid(), signal.SIGINT)


def test_ctrl_c_landing_while_the_workers_fork_prints_no_traceback(capfd):
    # a Ctrl-C in the instant a worker is forked used to raise inside the child's at-fork
    # handlers (logging's lock), which print "Exception ignored ... Traceback"; held until the
    # worker's own code runs, it is one more Ctrl-C the evaluation reports
    from rrls.evaluation import MLPPolicy, evaluate

    if not _MID_FORK["registered"]:  # os.register_at_fork has no undo: once per process
        os.register_at_fork(after_in_child=_ctrl_c_in_the_child)
        _MID_FORK["registered"] = True
    policy = MLPPolicy.random(11, 3, (8,), seed=0)
    before = signal.signal(signal.SIGINT, signal.default_int_handler)  # as in a terminal
    _MID_FORK["armed"] = True
    try:
        with pytest.raises(KeyboardInterrupt):
            evaluate(policy, "hopper", "1d", mesh=4, episodes=4, workers=2)
    finally:
        _MID_FORK["armed"] = False
        signal.signal(signal.SIGINT, before)
    err = capfd.readouterr().err
    assert "Traceback" not in err and "Exception ignored" not in err, err


def test_a_child_started_with_stops_held_meets_ctrl_c_once_its_own_handlers_are_set():
    # a benchmark's run processes are spawned: a Ctrl-C while one's interpreter is still
    # starting raised there (a traceback) before it could ignore it, as its driver expects
    import sys

    from rrls._proc import stops_held

    code = "import signal, time; time.sleep(1.5); signal.signal(signal.SIGINT, signal.SIG_IGN); "
    code += "from rrls._proc import release_stops; release_stops(); print('on')"
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    with stops_held():
        proc = subprocess.Popen(
            [sys.executable, "-c", code], env=env, text=True,
            stdout=subprocess.PIPE, stderr=subprocess.PIPE,
        )  # fmt: skip
    proc.send_signal(signal.SIGINT)  # while it starts
    out, err = proc.communicate(timeout=60)
    assert (proc.returncode, out.strip()) == (0, "on") and "Traceback" not in err, err


@pytest.fixture
def two_player_run(tmp_path):
    """A parameter-game run directory: random protagonist and adversary on InvertedPendulum."""
    run = tmp_path / "run"
    run.mkdir()
    meta = {"task": "invertedpendulum", "uncertainty": "2d"}
    _policy(run / "policy.npz", 4, 1, **meta)
    _policy(run / "adversary.npz", 4, 2, game="adversarial", **meta)
    return run


@pytest.mark.e2e
def test_ctrl_c_in_evaluate_dynamic_names_the_chunks_kept_in_out(
    tmp_path, capsys, monkeypatch, stop_after_chunks, two_player_run
):
    from rrls.cli import main

    monkeypatch.chdir(tmp_path)
    argv = ["evaluate-dynamic", "run", "--episodes", "220", "--workers", "0", "--out", "dy"]
    stop_after_chunks(3)
    assert main(argv) == 130
    assert _chunks(tmp_path / "dy") == 3
    assert _line(capsys) == (
        "rrls evaluate-dynamic: interrupted; 150 of 220 episodes (3 of 5 chunks) kept in dy; "
        "to go on: rrls " + " ".join(argv)
    )
    saved = stop_after_chunks(99)
    assert main(argv) == 0 and len(saved) == 2  # the same command: the 2 chunks left


@pytest.mark.e2e
def test_ctrl_c_in_evaluate_dynamic_without_out_says_nothing_is_kept(
    tmp_path, capsys, monkeypatch, two_player_run
):
    from rrls.cli import main
    from rrls.evaluation import engine

    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(engine, "run", _ctrl_c)
    argv = ["evaluate-dynamic", "run", "--episodes", "220", "--workers", "0"]
    assert main(argv) == 130
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run"]  # nothing written
    assert _line(capsys) == (
        "rrls evaluate-dynamic: interrupted; nothing kept (without --out no episode is saved); "
        "to start again: rrls " + " ".join(argv)
    )


@pytest.mark.e2e
def test_ctrl_c_in_train_before_the_first_checkpoint_says_nothing_is_kept(
    tmp_path, capsys, monkeypatch
):
    pytest.importorskip("torch")
    from rrls.agents.run import Run
    from rrls.cli import main

    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(Run, "load", _ctrl_c)  # Ctrl-C while the run sets up
    argv = ["train", "--algo", "td3", "--task", "invertedpendulum", "--steps", "1000"]
    argv += ["--learning-starts", "100", "--checkpoint-every", "200", "--out", "run"]
    assert main(argv) == 130
    assert not (tmp_path / "run" / "checkpoint.pt").exists()
    assert _line(capsys) == (
        "rrls train: interrupted; no checkpoint yet (the first at step 200): nothing kept in "
        "run; to start again: rrls " + " ".join(argv)
    )


def _fake_runs(kept: dict[str, str]):
    """A stand-in for the local backend: writes ``{run name: file}`` then Ctrl-C."""

    def run_local(root, spec, todo, *rest):
        names = [key.name(spec.uncertainty) for key in todo]
        for name, file in zip(names, kept.values()):
            (root / "runs" / name).mkdir(parents=True, exist_ok=True)
            (root / "runs" / name / file).write_text("{}")
        raise KeyboardInterrupt

    return run_local


@pytest.mark.parametrize("command", ["benchmark", "quickstart"])
def test_ctrl_c_in_a_benchmark_counts_the_runs_kept(tmp_path, capsys, monkeypatch, command):
    pytest.importorskip("torch")
    from rrls.benchmark import runner
    from rrls.cli import main

    monkeypatch.chdir(tmp_path)
    files = {"a": "result.json", "b": "result.json", "c": "checkpoint.pt"}
    monkeypatch.setattr(runner, "run_local", _fake_runs(files))
    if command == "benchmark":
        argv = ["benchmark", "--preset", "smoke", "--workers", "1", "--out", "b"]
    else:
        argv = ["quickstart", "--out", "b", "--steps", "1000", "--seeds", "0"]
    assert main(argv) == 130
    runs = tmp_path / "b" / "runs"
    assert len(list(runs.glob("*/result.json"))) == 2 and len(list(runs.glob("*/*.pt"))) == 1
    assert not (tmp_path / "b" / "report").exists()  # no report of a grid not run
    assert _line(capsys) == (
        f"rrls {command}: interrupted; 2 of 5 runs finished in b/runs; of the 3 others, 1 with "
        "a checkpoint (their training goes on); to go on: rrls " + " ".join(argv)
    )


def test_ctrl_c_in_report_says_which_folders_were_rewritten(tmp_path, capsys, monkeypatch):
    from rrls.benchmark import changes, store
    from rrls.cli import main
    from rrls.report import writer as report

    (tmp_path / "runs").mkdir()
    (tmp_path / "report").mkdir()
    (tmp_path / "report" / "report.md").write_text("the earlier report")

    def rebuilt(root, expected=None):  # the store rebuilt whole, then Ctrl-C in the report
        return changes.rebuild_folder(root, "results", lambda out: (out / "runs.csv").touch())

    monkeypatch.setattr(store, "build_store", rebuilt)
    monkeypatch.setattr(report, "make_report", _ctrl_c)
    assert main(["report", str(tmp_path)]) == 130
    assert (tmp_path / "results" / "runs.csv").exists()
    assert (tmp_path / "report" / "report.md").read_text() == "the earlier report"
    assert _line(capsys) == (
        f"rrls report: interrupted; {tmp_path / 'results'} rewritten; {tmp_path / 'report'} as "
        f"before, whole; to go on: rrls report {tmp_path}"
    )


def test_ctrl_c_in_submit_says_whether_anything_was_submitted(
    tmp_path, capsys, monkeypatch, stop_after_chunks
):
    from rrls.cli import main
    from rrls.submissions import steps as submission

    monkeypatch.chdir(tmp_path)
    _policy(tmp_path / "p.npz", 4, 1)
    argv = ["submit", "b", "p.npz", "--algo", "mine", "--task", "invertedpendulum", "--seed", "0"]
    argv += ["--preset", "quick", "--workers", "0"]
    stop_after_chunks(0)  # mid-evaluation
    assert main(argv) == 130
    assert not list(tmp_path.glob("b/runs/*"))
    staged = sorted(tmp_path.glob(f"b/submissions/.staging/*-{os.getpid()}-*"))
    kept = (
        f"its partial evaluation is left in {staged[0].relative_to(tmp_path)}, which no re-run "
        "uses: delete it"
        if staged
        else "nothing kept: a re-run evaluates from the start"
    )
    line = _line(capsys)
    assert line.startswith("rrls submit: interrupted; nothing was submitted")
    assert kept in line and line.endswith("; to start again: rrls " + " ".join(argv))

    real = submission.submit

    def submitted_then_interrupted(*args, **kwargs):
        real(*args, **kwargs)
        raise KeyboardInterrupt

    stop_after_chunks(99)
    monkeypatch.setattr(submission, "submit", submitted_then_interrupted)
    assert main(argv) == 130
    (run,) = tmp_path.glob("b/runs/*")
    assert (run / "result.json").exists()
    assert (
        _line(capsys)
        == f"rrls submit: interrupted; the submission is stored in {run.relative_to(tmp_path)}"
    )


def test_ctrl_c_in_withdraw_says_whether_the_runs_are_gone(tmp_path, capsys, monkeypatch):
    from rrls.cli import main
    from rrls.submissions import withdraw

    monkeypatch.chdir(tmp_path)
    _policy(tmp_path / "p.npz", 4, 1)
    submit = ["submit", "b", "p.npz", "--algo", "mine", "--task", "invertedpendulum", "--seed"]
    for seed in ("0", "1"):
        assert main([*submit, seed, "--preset", "quick", "--workers", "0"]) == 0
    argv = ["withdraw", "b", "--algo", "mine"]
    real = withdraw.remove_submission
    monkeypatch.setattr(withdraw, "remove_submission", _ctrl_c)
    capsys.readouterr()
    assert main(argv) == 130
    assert len(list(tmp_path.glob("b/runs/*/result.json"))) == 2
    assert _line(capsys) == (
        "rrls withdraw: interrupted; nothing withdrawn (all or nothing): 2 submitted run(s) of "
        "mine still in b/runs; to go on: rrls withdraw b --algo mine"
    )

    def withdrawn_then_interrupted(*args):
        real(*args)
        raise KeyboardInterrupt

    monkeypatch.setattr(withdraw, "remove_submission", withdrawn_then_interrupted)
    assert main(argv) == 130
    assert not list(tmp_path.glob("b/runs/*/result.json"))
    assert _line(capsys) == (
        "rrls withdraw: interrupted; the withdrawal is complete: no submitted run of mine left "
        "in b/runs"
    )


def test_ctrl_c_in_check_and_plot_says_what_was_written(tmp_path, capsys, monkeypatch):
    import rrls.check
    from rrls.cli import main
    from rrls.evaluation import evaluate, result_plot

    monkeypatch.setattr(rrls.check, "main", _ctrl_c)
    assert main(["check", "--task", "hopper"]) == 130
    assert _line(capsys) == (
        "rrls check: interrupted; nothing written (rrls check writes no file); to start again: "
        "rrls check --task hopper"
    )
    from rrls.evaluation import MLPPolicy

    ev = tmp_path / "ev"
    evaluate(
        MLPPolicy.random(11, 3, (8,)), "hopper", "1d", mesh=2, episodes=1, workers=1, out_dir=ev
    )
    monkeypatch.setattr(result_plot, "atomic_write_bytes", _ctrl_c)
    assert main(["plot", str(ev)]) == 130
    assert not (ev / "returns.png").exists()
    assert _line(capsys) == (
        f"rrls plot: interrupted; {ev / 'returns.png'} not written; to start again: rrls plot {ev}"
    )
