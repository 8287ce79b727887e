"""``rrls train`` holds its run directory's lock, as a benchmark's runs and ``submit`` do: a
second command writing the same directory is refused in one line, and nothing it would have
written (a second copy of every curve row) reaches the first run's files."""

from __future__ import annotations

import subprocess
import sys
import textwrap

import pytest

pytest.importorskip("torch")

from rrls.cli import main
from rrls.files import DirectoryLock

HOLD = textwrap.dedent(
    """
    import sys, time
    from rrls.files import DirectoryLock
    with DirectoryLock(sys.argv[1]):
        print("held", flush=True)
        time.sleep(60)
    """
)


def test_a_second_train_into_a_held_directory_is_refused_in_one_line(tmp_path, capsys):
    out = tmp_path / "run"
    holder = subprocess.Popen([sys.executable, "-c", HOLD, str(out)], stdout=subprocess.PIPE)
    try:
        assert holder.stdout.readline().strip() == b"held"
        argv = ["train", "--algo", "td3", "--task", "invertedpendulum", "--steps", "50"]
        argv += ["--learning-starts", "20", "--eval-every", "0", "--out", str(out)]
        code = main(argv)
        err = capsys.readouterr().err.strip().splitlines()
    finally:
        holder.kill()
        holder.wait()
    assert code == 2
    assert len(err) == 1 and "in use by another running rrls command" in err[0], err
    assert str(out) in err[0]
    assert not (out / "scalars.csv").exists()
    # the holder gone, the same command trains
    assert main(argv) == 0 and (out / "policy.npz").exists()


def test_a_process_nests_its_own_locks_but_another_may_not(tmp_path):
    with DirectoryLock(tmp_path), DirectoryLock(tmp_path):  # a run inside its benchmark's lock
        pass
    with DirectoryLock(tmp_path):
        probe = "from rrls.files import DirectoryLock; import sys\n"
        probe += "try:\n    DirectoryLock(sys.argv[1]).__enter__()\nexcept FileExistsError:\n"
        probe += "    sys.exit(7)\n"
        code = subprocess.run([sys.executable, "-c", probe, str(tmp_path)]).returncode
    assert code == 7
    # released: another process may take it now
    assert subprocess.run([sys.executable, "-c", probe, str(tmp_path)]).returncode == 0


def test_another_thread_of_the_same_process_may_not_take_a_held_lock(tmp_path):
    import threading

    refused = []

    def probe() -> None:
        try:
            with DirectoryLock(tmp_path):
                pass
        except FileExistsError as err:
            refused.append(str(err))

    with DirectoryLock(tmp_path):
        t = threading.Thread(target=probe)
        t.start()
        t.join()
    assert refused and "in use by another running rrls command" in refused[0]


def test_a_resume_under_other_settings_names_each_difference(tmp_path, capsys, monkeypatch):
    out = tmp_path / "run"
    argv = ["train", "--algo", "td3", "--task", "invertedpendulum", "--steps", "80"]
    argv += ["--learning-starts", "20", "--eval-every", "0", "--checkpoint-every", "40"]
    argv += ["--out", str(out)]
    monkeypatch.setenv("RRLS_STOP_AT", "40")
    assert main([*argv, "--physics", "paper"]) == 3  # stopped after its first checkpoint
    monkeypatch.delenv("RRLS_STOP_AT")
    capsys.readouterr()
    assert main([*argv, "--resume", "--learning-rate", "0.01"]) == 2
    line = capsys.readouterr().err.strip().splitlines()[-1]
    assert "cannot resume" in line
    assert "physics 'paper' (now 'v5')" in line and "learning_rate 0.0003 (now 0.01)" in line


def test_a_report_waits_for_another_report_of_the_same_benchmark(tmp_path, capsys):
    """``rrls report`` rebuilds results/ and report/: a second one (or a benchmark ending)
    waits for the first instead of mixing the files."""
    import threading

    from rrls.benchmark import benchfile
    from rrls.cli import main

    (tmp_path / "runs").mkdir()
    codes: list[int] = []
    with benchfile.reporting(tmp_path):
        other = threading.Thread(target=lambda: codes.append(main(["report", str(tmp_path)])))
        other.start()
        other.join(timeout=1.5)
        assert other.is_alive() and not codes  # waiting for the lock
    other.join(timeout=60)
    assert codes and codes[0] == 2  # then ran: this benchmark has no finished run
    assert "no run" in capsys.readouterr().err
