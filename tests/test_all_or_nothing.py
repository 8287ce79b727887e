"""Commands that change a benchmark change it all or not at all: ``submit`` (a new task, an
earlier submission replaced) and ``withdraw``. Each file-system step (every rename, atomic
write and directory creation) is failed in turn, and the benchmark directory is compared byte
for byte with its state before (lock files aside: an empty ``flock`` file a command may leave).

The benchmark is a submissions-only smoke protocol (InvertedPendulum and the double pendulum,
1D set, mesh 2 x 1 episode): a submission evaluates in well under a second.
"""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import numpy as np
import pytest

from rrls import files, rundir
from rrls.benchmark.benchfile import read_spec
from rrls.cli import main
from rrls.evaluation import BatchInvariant
from rrls.submissions import submit
from rrls.submissions.steps import SubmitError, create_benchmark
from rrls.submissions.withdraw import remove_submission

LOCKS = {".benchmark.lock", ".report.lock", ".lock"}


class Linear(BatchInvariant):
    """A fixed linear controller (batch-invariant: exact episodes) with metadata."""

    def __init__(self, *gains: float, metadata: dict | None = None) -> None:
        k = np.asarray(gains, dtype=float)
        super().__init__(lambda obs: np.clip((obs[:, : k.size] @ k)[:, None], -1.0, 1.0))
        self.metadata = metadata or {}


def snapshot(root: Path) -> dict[str, bytes | None]:
    """Every file's bytes and every folder (None) under ``root``, lock files aside."""
    out: dict[str, bytes | None] = {}
    for path in sorted(root.rglob("*")):
        if path.name in LOCKS:
            continue
        out[str(path.relative_to(root))] = None if path.is_dir() else path.read_bytes()
    return out


@pytest.fixture
def bench(tmp_path) -> Path:
    """A submissions-only benchmark: ``mine`` on both tasks, ``other`` on the pendulum."""
    root = tmp_path / "bench"
    create_benchmark(root, "smoke", ("invertedpendulum",))
    submit(root, "mine", "invertedpendulum", 0, Linear(1.0, 0.0), workers=1, progress=False)
    submit(
        root, "mine", "inverteddoublependulum", 0, Linear(0.5), workers=1, progress=False,
        add_task=True,
    )  # fmt: skip
    submit(root, "other", "invertedpendulum", 0, Linear(0.0, 1.0), workers=1, progress=False)
    return root


class Fault:
    """Fail the ``at``-th file-system step (``os.rename``, ``os.replace``, ``os.mkdir``)."""

    def __init__(self, monkeypatch: pytest.MonkeyPatch, at: int | None) -> None:
        self.at, self.calls = at, 0
        for name in ("rename", "replace", "mkdir"):
            monkeypatch.setattr(os, name, self.wrap(getattr(os, name)))

    def wrap(self, real):
        def step(*args, **kwargs):
            self.calls += 1
            if self.calls == self.at:
                raise OSError(28, "No space left on device (injected)")
            return real(*args, **kwargs)

        return step


def succeed(action, root: Path, copy: Path) -> tuple[int, set[str]]:
    """The file-system steps ``action`` takes on a copy of ``root`` when nothing fails, and
    the paths it leaves."""
    shutil.copytree(root, copy)
    with pytest.MonkeyPatch.context() as mp:
        fault = Fault(mp, None)
        action(copy)
    paths = set(snapshot(copy))
    shutil.rmtree(copy)
    return fault.calls, paths


def fail_each_step(action, bench, tmp_path, n, before, done, name, errors) -> int:
    """Fail each of ``action``'s ``n`` file-system steps in turn on a fresh copy of ``bench``:
    it raises one of ``errors`` and leaves the copy as ``before``, or (a step whose failure is
    harmless) finishes whole (the paths ``done``). Returns how many failures were felt."""
    failed = 0
    for at in range(1, n + 1):
        copy = tmp_path / f"at{at}"
        shutil.copytree(bench, copy)
        with pytest.MonkeyPatch.context() as mp:
            Fault(mp, at)
            try:
                action(copy)
            except errors:
                failed += 1
                assert snapshot(copy) == before, f"{name}: step {at} of {n} left changes"
            else:
                after = snapshot(copy)
                assert set(after) == done and after != before, f"{name}: step {at} half done"
        shutil.rmtree(copy)
    return failed


ACTIONS = {
    "submit --overwrite": lambda r: submit(
        r,
        "mine",
        "invertedpendulum",
        0,
        Linear(2.0, 0.5),
        overwrite=True,
        workers=1,
        progress=False,
    ),  # fmt: skip
    "submit --add-task": lambda r: submit(
        r,
        "other",
        "inverteddoublependulum",
        0,
        Linear(0.3),
        add_task=True,
        workers=1,
        progress=False,
    ),  # fmt: skip
    "withdraw (task list shrinks)": lambda r: remove_submission(
        r, "mine", task="inverteddoublependulum"
    ),
    "withdraw (every run of an algorithm)": lambda r: remove_submission(r, "mine"),
}


@pytest.mark.parametrize("name", list(ACTIONS))
def test_a_failure_at_any_step_leaves_the_benchmark_as_it_was(bench, tmp_path, name):
    """Each step failed in turn, on a fresh copy: the command fails and leaves the benchmark
    as it was, or (a step whose failure is harmless: a folder that exists already) finishes
    whole."""
    action = ACTIONS[name]
    n, done = succeed(action, bench, tmp_path / "count")
    assert n >= 3, f"{name}: only {n} file-system steps counted"
    before = snapshot(bench)
    failed = fail_each_step(action, bench, tmp_path, n, before, done, name, (OSError, SubmitError))
    assert failed >= n // 2, f"{name}: only {failed} of {n} injected faults were felt"


def test_the_earlier_submission_survives_a_refused_overwrite(bench):
    run = bench / "runs" / "mine-invertedpendulum-1d-seed0"
    before = snapshot(bench)
    old = files.read_checked_json(run / rundir.RESULT)
    bad = Linear(2.0, 0.5, metadata={"steps": -5})
    with pytest.raises(SubmitError, match="steps -5"):
        submit(bench, "mine", "invertedpendulum", 0, bad, overwrite=True, workers=1)
    assert snapshot(bench) == before
    assert files.read_checked_json(run / rundir.RESULT) == old


@pytest.mark.parametrize("steps", [-5, True, 2.5, "many"])
def test_bad_declared_steps_are_refused_before_the_evaluation(bench, steps):
    before = snapshot(bench)
    bad = Linear(0.3, metadata={"steps": steps})
    with pytest.raises(SubmitError, match="metadata records steps"):
        submit(bench, "new", "inverteddoublependulum", 0, bad, add_task=True, workers=1)
    assert snapshot(bench) == before
    assert "inverteddoublependulum" in read_spec(bench).tasks  # from the fixture, unchanged


@pytest.mark.parametrize("key", ["steps", "declared_by", " "])
def test_reserved_budget_keys_are_refused(bench, key):
    before = snapshot(bench)
    with pytest.raises(SubmitError, match="reserved"):
        submit(bench, "new", "invertedpendulum", 0, Linear(0.1), budget={key: "the benchmark"})
    assert snapshot(bench) == before


def test_a_repeated_budget_key_is_refused_in_one_line(bench, tmp_path, capsys):
    policy = tmp_path / "p.npz"
    np.savez(policy, w=np.zeros(1))
    code = main(
        ["submit", str(bench), str(policy), "--algo", "x", "--task", "invertedpendulum",
         "--seed", "0", "--budget", "gpu=1", "--budget", "gpu=2"]
    )  # fmt: skip
    err = capsys.readouterr().err.strip()
    assert code == 2 and len(err.splitlines()) == 1 and "'gpu' is given twice" in err


def test_withdraw_with_a_damaged_result_elsewhere_changes_nothing(bench):
    other = bench / "runs" / "other-invertedpendulum-1d-seed0" / rundir.RESULT
    other.write_bytes(other.read_bytes().replace(b"other", b"otheR"))
    before = snapshot(bench)
    with pytest.raises(SubmitError, match="damaged.*nothing was withdrawn"):
        remove_submission(bench, "mine", task="inverteddoublependulum")
    assert snapshot(bench) == before


@pytest.mark.parametrize("task", ["InvertedDoublePendulum", "inverted_double_pendulum"])
def test_withdraw_takes_every_spelling_submit_takes(bench, task, capsys):
    assert main(["withdraw", str(bench), "--algo", "MINE", "--task", task]) == 0
    assert "mine-inverteddoublependulum-1d-seed0" in capsys.readouterr().out
    assert read_spec(bench).tasks == ("invertedpendulum",)


def test_a_failed_store_rebuild_keeps_the_old_store(bench, tmp_path):
    """The result store is rebuilt beside the old one and swapped in whole."""
    from rrls.benchmark.store import build_store

    build_store(bench)
    remove_submission(bench, "other")  # the next rebuild differs
    n, done = succeed(build_store, bench, tmp_path / "count")
    fail_each_step(build_store, bench, tmp_path, n, snapshot(bench), done, "store", (OSError,))


def test_a_failed_report_keeps_the_old_report(bench, tmp_path, monkeypatch):
    """The report is built beside the old one and swapped in whole: a failure while writing
    its figures leaves every file of the old report in place."""
    from rrls.benchmark.store import build_store
    from rrls.report import plots
    from rrls.report.writer import make_report

    build_store(bench)
    make_report(bench, plots=False)
    before = snapshot(bench)

    def broken(*args, **kwargs):
        raise OSError(28, "No space left on device (injected)")

    monkeypatch.setattr(plots, "make_figures", broken)
    with pytest.raises(OSError, match="injected"):
        make_report(bench)
    assert snapshot(bench) == before


@pytest.mark.parametrize("value", [True, None, float("nan"), {"a": 1}])
def test_budget_values_that_are_not_text_or_numbers_are_refused(bench, value):
    before = snapshot(bench)
    with pytest.raises(SubmitError, match="valid: text or a finite number"):
        submit(bench, "new", "invertedpendulum", 0, Linear(0.1), budget={"gpu": value})
    assert snapshot(bench) == before


@pytest.mark.parametrize("meta", [{"alpha": None, "game": "nr"}, {"game": "chess"}])
def test_an_adversarys_bad_metadata_is_refused_in_one_line(bench, meta):
    before = snapshot(bench)
    adversary = Linear(0.2, 0.0, metadata=meta)
    with pytest.raises(SubmitError, match="metadata") as err:
        submit(bench, "new", "invertedpendulum", 0, Linear(0.1), adversary=adversary)
    assert "\n" not in str(err.value) and snapshot(bench) == before
