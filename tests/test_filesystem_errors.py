"""Filesystem errors are one line and exit 2 in every command that writes: a read-only output,
a full disk, a directory where a file is expected. The read-only and full file systems are
real (a tmpfs mounted for the test); without the privilege to mount one, those tests skip."""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import pytest

from rrls._progress import PLAIN_LINE
from rrls.cli import main
from rrls.evaluation.policies import MLPPolicy

EVAL = ["--task", "invertedpendulum", "--uncertainty", "1d", "--mesh", "2", "--episodes", "1"]
TRAIN = ["train", "--algo", "td3", "--task", "invertedpendulum", "--learning-starts", "20"]
TRAIN += ["--eval-every", "0"]


def _mount(path: Path, options: str) -> None:
    path.mkdir(parents=True, exist_ok=True)
    done = subprocess.run(
        ["mount", "-t", "tmpfs", "-o", options, "tmpfs", str(path)], capture_output=True
    )
    if done.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here ({done.stderr.decode().strip() or 'no mount'})")


@pytest.fixture
def readonly(tmp_path):
    path = tmp_path / "ro"
    _mount(path, "ro,size=1m")
    yield path
    subprocess.run(["umount", str(path)], check=False)


@pytest.fixture
def tiny(tmp_path):
    path = tmp_path / "tiny"
    _mount(path, "size=48k")
    yield path
    subprocess.run(["umount", str(path)], check=False)


def one_line(capsys) -> str:
    """The error's line (progress bars aside): one, and no traceback."""
    err = capsys.readouterr().err
    lines = [
        line
        for line in err.strip().splitlines()
        if "%|" not in line and not PLAIN_LINE.match(line)  # a bar, or a log's progress line
    ]
    assert len(lines) == 1, lines
    assert "Traceback" not in err
    return lines[0]


@pytest.fixture
def policy(tmp_path) -> str:
    return str(MLPPolicy.random(4, 1, hidden=(8,), seed=0).save(tmp_path / "p.npz"))


def test_evaluate_into_a_read_only_directory(readonly, policy, capsys):
    assert main(["evaluate", policy, *EVAL, "--workers", "0", "--out", str(readonly / "e")]) == 2
    line = one_line(capsys)
    assert line.startswith("rrls evaluate: error:") and "read-only" in line


def test_train_into_a_read_only_directory(readonly, capsys):
    pytest.importorskip("torch")
    assert main([*TRAIN, "--steps", "40", "--out", str(readonly / "run")]) == 2
    assert "read-only" in one_line(capsys)


def test_benchmark_into_a_read_only_directory(readonly, capsys):
    pytest.importorskip("torch")
    argv = ["benchmark", "--preset", "smoke", "--algos", "td3", "--out", str(readonly / "b")]
    assert main(argv) == 2
    assert "read-only" in one_line(capsys)


@pytest.mark.e2e
def test_train_on_a_full_disk(tiny, capsys):
    pytest.importorskip("torch")
    code = main([*TRAIN, "--steps", "2000", "--checkpoint-every", "500", "--out", str(tiny / "r")])
    assert code == 2
    assert "disk is full" in one_line(capsys)


def test_evaluate_on_a_full_disk(tiny, policy, capsys):
    filler = tiny / "filler"
    filler.write_bytes(b"x" * 40_000)  # what is left is less than the summary needs
    code = main(["evaluate", policy, *EVAL, "--workers", "0", "--out", str(tiny / "e")])
    if code == 0:  # it fitted: nothing to check on this file system
        pytest.skip("the evaluation's files fitted in what was left")
    assert code == 2 and "disk is full" in one_line(capsys)


@pytest.mark.e2e
def test_a_report_of_a_read_only_benchmark(tmp_path, readonly, capsys):
    pytest.importorskip("torch")
    bench = tmp_path / "bench"
    argv = ["benchmark", "--preset", "smoke", "--algos", "td3", "--out", str(bench)]
    assert main(argv) == 0
    shutil.rmtree(bench / "report")
    subprocess.run(["umount", str(readonly)], check=True)
    _mount(readonly, "size=8m")
    shutil.copytree(bench, readonly / "bench")
    subprocess.run(["mount", "-o", "remount,ro", str(readonly)], check=True)
    capsys.readouterr()
    assert main(["report", str(readonly / "bench")]) == 2
    assert "read-only" in one_line(capsys)


@pytest.mark.parametrize("dry", [True, False])
def test_benchmark_out_a_regular_file_is_refused_dry_run_too(tmp_path, capsys, dry):
    pytest.importorskip("torch")
    out = tmp_path / "file"
    out.write_text("not a directory")
    argv = ["benchmark", "--preset", "smoke", "--algos", "td3", "--out", str(out)]
    assert main(argv + (["--dry-run"] if dry else [])) == 2
    assert "is a file, not a directory" in one_line(capsys)


@pytest.fixture(scope="module")
def smoke_bench(tmp_path_factory) -> Path:
    """A finished one-run benchmark with one submitted policy (made once for the module)."""
    pytest.importorskip("torch")
    root = tmp_path_factory.mktemp("fs") / "bench"
    assert main(["benchmark", "--preset", "smoke", "--algos", "td3", "--out", str(root)]) == 0
    policy = MLPPolicy.random(4, 1, hidden=(8,), seed=1).save(root.parent / "mine.npz")
    argv = ["submit", str(root), str(policy), "--algo", "mine", "--task", "invertedpendulum"]
    assert main([*argv, "--seed", "0"]) == 0
    return root


def _copy_onto(fs: Path, bench: Path, remount: str | None) -> Path:
    """``bench`` copied onto the mounted ``fs`` (8 MiB), then remounted with ``remount``."""
    subprocess.run(["umount", str(fs)], check=True)
    _mount(fs, "size=8m")
    shutil.copytree(bench, fs / "bench")
    if remount:
        subprocess.run(["mount", "-o", f"remount,{remount}", str(fs)], check=True)
    return fs / "bench"


def _fill(fs: Path) -> None:
    """Leave (almost) nothing free on ``fs``."""
    with open(fs / "filler", "wb") as f:
        try:
            while True:
                f.write(b"x" * 65536)
        except OSError:
            pass


COMMANDS = {
    "report": lambda b: ["report", str(b), "--no-plots"],
    "export-reference": lambda b: ["report", str(b), "--no-plots", "--export-reference",
                                   str(b / "ref.json")],
    "submit": lambda b: ["submit", str(b), str(b.parent / "p.npz"), "--algo", "other", "--task",
                         "invertedpendulum", "--seed", "0"],
    "withdraw": lambda b: ["withdraw", str(b), "--algo", "mine"],
    "evaluate-run": lambda b: ["evaluate", str(b / "runs" / "td3-invertedpendulum-1d-seed0"),
                               "--mesh", "2", "--episodes", "1", "--workers", "0", "--out",
                               str(b / "again")],
}  # fmt: skip


@pytest.mark.e2e
@pytest.mark.parametrize("command", sorted(COMMANDS))
@pytest.mark.parametrize("where", ["read-only", "full"])
def test_every_command_on_a_read_only_or_full_file_system(
    smoke_bench, readonly, command, where, capsys
):
    bench = _copy_onto(readonly, smoke_bench, "ro" if where == "read-only" else None)
    if where == "full":
        MLPPolicy.random(4, 1, hidden=(8,), seed=2).save(readonly / "p.npz")
        _fill(readonly)
    else:
        subprocess.run(["mount", "-o", "remount,rw", str(readonly)], check=True)
        MLPPolicy.random(4, 1, hidden=(8,), seed=2).save(readonly / "p.npz")
        subprocess.run(["mount", "-o", "remount,ro", str(readonly)], check=True)
    capsys.readouterr()
    code = main(COMMANDS[command](bench))
    if code == 0 and where == "full":
        pytest.skip("what the command writes fitted in what was left")
    assert code == 2
    line = one_line(capsys)
    assert ("read-only" if where == "read-only" else "disk is full") in line, line
