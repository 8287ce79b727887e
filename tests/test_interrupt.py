"""Ctrl-C anywhere: one line that says what was kept and the exact command that goes on, exit
status 130, no traceback and no leaked-resource warning (the commands run as a terminal runs
them: SIGINT to the whole process group)."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
POLICY = "import numpy as np\n\ndef zeros(obs):\n    return np.zeros((len(obs), 3))\n"


def _interrupt(args: list[str], cwd: Path, ready: Path) -> subprocess.CompletedProcess:
    """Run ``rrls ARGS``, press Ctrl-C once ``ready`` exists, and return what it printed."""
    # Python leaves SIGINT ignored if it starts ignored (a suite launched in the background by a
    # non-interactive shell): give the child Ctrl-C's default, as a terminal would
    code = "import signal, sys; signal.signal(signal.SIGINT, signal.default_int_handler); "
    code += f"from rrls.cli import main; sys.exit(main({args!r}))"
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    proc = subprocess.Popen(
        [sys.executable, "-c", code], cwd=cwd, env=env, text=True, start_new_session=True,
        stdout=subprocess.PIPE, stderr=subprocess.PIPE,
    )  # fmt: skip
    deadline = time.time() + 120
    while not ready.exists() and proc.poll() is None and time.time() < deadline:
        time.sleep(0.2)
    time.sleep(1.0)
    if proc.poll() is None:
        os.killpg(proc.pid, signal.SIGINT)
    try:
        out, err = proc.communicate(timeout=120)
    except subprocess.TimeoutExpired:  # never leave a run training behind a failed test
        os.killpg(proc.pid, signal.SIGKILL)
        proc.communicate()
        raise
    return subprocess.CompletedProcess(args, proc.returncode, out, err)


def _check(done: subprocess.CompletedProcess, line: str) -> None:
    assert done.returncode == 130, done.stderr[-2000:]
    assert "Traceback" not in done.stderr and "leaked" not in done.stderr
    assert done.stderr.strip().splitlines()[-1] == line


def test_ctrl_c_in_train_says_what_was_kept_and_how_to_resume(tmp_path):
    pytest.importorskip("torch")
    args = ["train", "--algo", "td3", "--task", "invertedpendulum", "--steps", "200000"]
    args += ["--learning-starts", "100", "--checkpoint-every", "200", "--out", "run"]
    done = _interrupt(args, tmp_path, tmp_path / "run" / "checkpoint.pt")
    _check(
        done,
        "rrls train: interrupted; checkpoints up to the last --checkpoint-every are kept; to go "
        "on: rrls " + " ".join(args) + " --resume",
    )


def test_ctrl_c_in_evaluate_keeps_finished_points_and_names_the_same_command(tmp_path):
    (tmp_path / "hop.py").write_text(POLICY)
    args = ["evaluate", "hop:zeros", "--task", "hopper", "--uncertainty", "3d", "--mesh", "12"]
    args += ["--episodes", "3", "--workers", "2", "--out", "ev"]
    done = _interrupt(args, tmp_path, tmp_path / "ev")
    _check(
        done,
        "rrls evaluate: interrupted; finished mesh points are kept in the output directory; to "
        "go on: rrls " + " ".join(args),
    )
