"""Progress under any terminal and in any log: ``rrls evaluate`` and ``rrls train`` draw a bar on
a terminal, even a pseudo-terminal that reports no size (tqdm alone hid the bar there), and
write plain lines (one per 10 % or per minute) where stderr is a pipe or a file."""

from __future__ import annotations

import fcntl
import os
import pty
import re
import struct
import subprocess
import sys
import termios
from pathlib import Path

import numpy as np
import pytest

from rrls._progress import (
    EVERY_SECONDS,
    PLAIN_LINE,
    PlainProgress,
    progress_bar,
    terminal_shape,
)

#: the long end-to-end tier (.ci/run runs it after the default suite)
pytestmark = pytest.mark.e2e

ROOT = Path(__file__).resolve().parent.parent
POLICY = "import numpy as np\n\ndef zeros(obs):\n    return np.zeros((len(obs), 1))\n"
EVALUATE = ["evaluate", "pol:zeros", "--task", "invertedpendulum", "--uncertainty", "1d"]
EVALUATE += ["--mesh", "20", "--episodes", "1", "--workers", "0", "--out", "ev"]
TRAIN = ["train", "--algo", "td3", "--task", "invertedpendulum", "--steps", "300"]
TRAIN += ["--hidden", "8", "8", "--learning-starts", "100", "--eval-every", "0", "--out", "run"]


def _rrls(args: list[str], cwd: Path, stderr: int) -> subprocess.Popen:
    env = {**os.environ, "PYTHONPATH": f"{ROOT}{os.pathsep}{cwd}", "TERM": "xterm"}
    for name in ("COLUMNS", "LINES"):
        env.pop(name, None)
    code = f"import sys; from rrls.cli import main; sys.exit(main({args!r}))"
    return subprocess.Popen(
        [sys.executable, "-c", code], cwd=cwd, env=env, stdout=subprocess.PIPE, stderr=stderr
    )


def _under_a_pty(args: list[str], cwd: Path) -> str:
    """What ``rrls ARGS`` writes on stderr when stderr is a pseudo-terminal of no size (0 x 0,
    as ``script`` or ``docker run -t`` give it)."""
    master, slave = pty.openpty()
    assert os.get_terminal_size(slave) == (0, 0)
    proc = _rrls(args, cwd, slave)
    os.close(slave)
    out = b""
    while True:
        try:
            chunk = os.read(master, 65536)
        except OSError:  # EIO: the child closed its end
            break
        if not chunk:
            break
        out += chunk
    os.close(master)
    assert proc.wait(timeout=300) == 0, out[-2000:]
    return out.decode("utf-8", "replace")


def _in_a_pipe(args: list[str], cwd: Path) -> list[str]:
    proc = _rrls(args, cwd, subprocess.PIPE)
    _, err = proc.communicate(timeout=300)
    assert proc.returncode == 0, err[-2000:]
    return err.decode().splitlines()


@pytest.fixture
def policy_module(tmp_path: Path) -> Path:
    (tmp_path / "pol.py").write_text(POLICY)
    return tmp_path


def test_evaluate_draws_a_bar_under_a_pseudo_terminal_without_a_size(policy_module):
    shown = _under_a_pty(EVALUATE, policy_module)
    assert re.search(r"evaluating: 100%\|█+\| 20/20", shown), shown[-1000:]


def test_evaluate_writes_plain_lines_into_a_pipe(policy_module):
    lines = _in_a_pipe(EVALUATE, policy_module)
    assert "\r" not in "".join(lines)
    progress = [line for line in lines if line.startswith("evaluating:")]
    assert all(PLAIN_LINE.match(line) for line in progress), progress
    assert progress[0].startswith("evaluating:   0% (0 of 20 episodes)")
    assert progress[-1].startswith("evaluating: 100% (20 of 20 episodes)")
    assert 2 <= len(progress) <= 100 // 10 + 2  # a line per 10 % at most, start and end


def test_train_draws_a_bar_under_a_pseudo_terminal_without_a_size(tmp_path):
    pytest.importorskip("torch")
    shown = _under_a_pty(TRAIN, tmp_path)
    assert re.search(r"td3 invertedpendulum: 100%\|█+\| 300/300", shown), shown[-1000:]


def test_train_writes_plain_lines_into_a_pipe(tmp_path):
    pytest.importorskip("torch")
    lines = _in_a_pipe(TRAIN, tmp_path)
    progress = [line for line in lines if line.startswith("td3 invertedpendulum:")]
    assert all(PLAIN_LINE.match(line) for line in progress), lines
    assert progress[0].startswith("td3 invertedpendulum:   0% (0 of 300 steps)")
    assert progress[-1].startswith("td3 invertedpendulum: 100% (300 of 300 steps)")
    assert re.search(r"ret -?\d+\.\d$", progress[-1])  # the last episode's return, as the bar
    assert len(progress) <= 12


# -- the pieces ------------------------------------------------------------------------------
class _Clock:
    def __init__(self) -> None:
        self.now = 0.0

    def __call__(self) -> float:
        return self.now


def test_plain_lines_come_every_tenth_or_every_minute_and_at_the_end(tmp_path):
    clock = _Clock()
    with open(tmp_path / "log", "w") as log:
        bar = PlainProgress(1000, unit="step", desc="run", stream=log, clock=clock)
        for _ in range(99):  # 9.9 %, quickly: no line
            bar.update(1)
        clock.now = 30.0
        bar.update(1)  # 10 %: a line
        clock.now = 30.0 + EVERY_SECONDS  # a minute later, still below 20 %: a line
        bar.update(50)
        bar.set_postfix(ret="3.5", refresh=False)
        bar.update(24)
        bar.close()
        bar.close()  # once
    lines = (tmp_path / "log").read_text().splitlines()
    assert lines == [
        "run:   0% (0 of 1,000 steps), 0:00 elapsed",
        "run:  10% (100 of 1,000 steps), 0:30 elapsed, 4:30 left",
        "run:  15% (150 of 1,000 steps), 1:30 elapsed, 8:30 left",
        "run:  17% (174 of 1,000 steps), 1:30 elapsed, 7:07 left, ret 3.5",
    ]


def test_a_plain_line_is_told_apart_from_a_commands_own_lines():
    assert PLAIN_LINE.match("pkg:Learner hopper:  10% (20 of 200 steps), 0:01 elapsed, ret 2.0")
    assert PLAIN_LINE.match("evaluating: 100% (1,000 of 1,000 episodes), 1:02:03 elapsed")
    assert not PLAIN_LINE.match("rrls train: error: training stopped at step 52: 10% off")


def test_a_resumed_count_starts_where_it_was():
    import io

    stream, clock = io.StringIO(), _Clock()
    bar = PlainProgress(
        200, unit="episode", desc="evaluating", initial=150, stream=stream, clock=clock
    )
    clock.now = 10.0
    bar.update(50)
    bar.close()
    assert stream.getvalue().splitlines() == [
        "evaluating:  75% (150 of 200 episodes), 0:00 elapsed",
        "evaluating: 100% (200 of 200 episodes), 0:10 elapsed",
    ]


def test_a_terminal_without_a_size_gets_one_and_a_sized_one_keeps_its_own(monkeypatch):
    monkeypatch.delenv("COLUMNS", raising=False)
    monkeypatch.delenv("LINES", raising=False)
    master, slave = pty.openpty()
    try:
        with open(slave, "w", closefd=False) as stream:
            assert terminal_shape(stream) == {"ncols": 79, "nrows": 23}
            monkeypatch.setenv("COLUMNS", "120")
            assert terminal_shape(stream) == {"ncols": 119, "nrows": 23}
            fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", 40, 100, 0, 0))
            assert terminal_shape(stream) == {}  # tqdm reads the real size itself
    finally:
        os.close(slave)
        os.close(master)


def test_the_library_default_stays_silent_off_a_terminal(capsys):
    from rrls.evaluation import evaluate

    def still(obs):
        return np.zeros((len(obs), 1))

    evaluate(still, "invertedpendulum", "1d", mesh=2, episodes=1, workers=1, max_episode_steps=5)
    assert capsys.readouterr().err == ""
    bar = progress_bar(10, unit="step", desc="x", shown=False)
    bar.update(10)
    bar.close()
    assert capsys.readouterr().err == ""
