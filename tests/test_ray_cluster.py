"""`rrls benchmark --backend ray` on a Ray cluster of several nodes on this machine, one of which
dies mid-run: the run it held is submitted again, resumes from its checkpoint on the node left,
and the same command finishes every run once, with a local run's numbers."""

from __future__ import annotations

import contextlib
import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from rrls.benchmark.backends import wait_for_locks
from rrls.files import DirectoryLock

REPO = Path(__file__).resolve().parents[1]
ALGOS = ["td3", "rarl"]
SMOKE = ["benchmark", "--preset", "smoke", "--algos", ",".join(ALGOS)]
RUNS = {f"{algo}-invertedpendulum-1d-seed0" for algo in ALGOS}
RUNS_RARL = "rarl-invertedpendulum-1d-seed0"


def _wait(condition, seconds: float, what: str, driver: subprocess.Popen) -> None:
    deadline = time.monotonic() + seconds
    while not condition():
        assert driver.poll() is None, f"the benchmark exited before {what}"
        assert time.monotonic() < deadline, f"no {what} after {seconds:.0f} s"
        time.sleep(0.05)


def _take(directory: Path, seconds: float) -> DirectoryLock:
    """``directory``'s lock, once its holder lets go."""
    deadline = time.monotonic() + seconds
    while True:
        try:
            return DirectoryLock(directory).__enter__()
        except FileExistsError:
            assert time.monotonic() < deadline, f"{directory} still held after {seconds:.0f} s"
            time.sleep(0.05)


def test_a_held_lock_is_waited_for_then_given_up(tmp_path):
    """What a group submitted again does first: the lost node's process may still hold its
    run directories for a moment."""
    import threading

    free, held = tmp_path / "free", tmp_path / "held"
    free.mkdir()
    assert wait_for_locks([free, tmp_path / "not-yet-made"], 0.0)
    taken, release = threading.Event(), threading.Event()

    def holder() -> None:  # another thread's lock is another holder's, as another process's
        with DirectoryLock(held):
            taken.set()
            release.wait(30)

    thread = threading.Thread(target=holder)
    thread.start()
    try:
        assert taken.wait(30)
        assert not wait_for_locks([free, held], 0.3, poll=0.05)
        threading.Timer(0.3, release.set).start()
        assert wait_for_locks([free, held], 30.0, poll=0.05)
    finally:
        release.set()
        thread.join()


class NodeDiedError(Exception):
    """Stands for Ray's (``run_ray`` says "node" by its name)."""


class _FakeRay:
    """What ``run_ray`` uses of Ray: each task's outcome is read from ``deaths`` (how many times
    each group's node dies before the group runs), the runs' results are left as they are."""

    def __init__(self, deaths: dict[str, int]) -> None:
        self.deaths, self.submitted = deaths, []
        self.exceptions = type(sys)("ray.exceptions")
        self.exceptions.NodeDiedError = NodeDiedError

    def is_initialized(self) -> bool:
        return True

    def remote(self, **_):
        fake = self

        class Task:
            @staticmethod
            def remote(root, spec_json, runs, wait):
                fake.submitted.append((runs[0][0], wait))
                return len(fake.submitted) - 1

        return lambda fn: Task

    def wait(self, refs, num_returns, timeout):
        return refs[:1], refs[1:]

    def get(self, ref):
        algo = self.submitted[ref][0]
        if self.deaths.get(algo, 0) > 0:
            self.deaths[algo] -= 1
            raise NodeDiedError("Task failed because the node it was running on is dead")

    def cancel(self, ref, force):
        pass


def test_a_group_whose_node_dies_goes_again_first_then_fails_after_three_more(
    tmp_path, monkeypatch, capsys
):
    from rrls.benchmark.backends import LOCK_WAIT_S, NODE_LOSS_RETRIES, run_ray
    from rrls.benchmark.grid import make_spec
    from rrls.benchmark.pipeline import run_dir

    spec = make_spec("smoke", algos="td3,rarl,dr")
    fake = _FakeRay({"td3": 1, "rarl": NODE_LOSS_RETRIES + 1})
    monkeypatch.setitem(sys.modules, "ray", fake)
    monkeypatch.setitem(sys.modules, "ray.exceptions", fake.exceptions)
    for key in spec.runs():  # what a run leaves when it finishes
        if key.algo != "rarl":
            run_dir(tmp_path, spec, key).mkdir(parents=True)
            (run_dir(tmp_path, spec, key) / "result.json").write_text("{}")
    events = []
    run_ray(tmp_path, spec, spec.runs(), 1, None, lambda *e: events.append(e), lambda: None)
    # one at a time (--workers 1): a lost group goes again before the groups not yet started,
    # and waits for its directories' locks then
    assert fake.submitted == [("td3", 0.0), ("td3", LOCK_WAIT_S)] + [("rarl", 0.0)] + [
        ("rarl", LOCK_WAIT_S)
    ] * NODE_LOSS_RETRIES + [("dr", 0.0)]
    assert [key.algo for key, state, _ in events if state == "running"] == ["td3", "rarl", "dr"]
    ends = {key.algo: (state, detail) for key, state, detail in events if state != "running"}
    assert ends["td3"] == ends["dr"] == ("done", "")
    assert ends["rarl"] == (
        "failed",
        "its Ray node died 4 times (NodeDiedError); re-run the same command to resume it",
    )
    err = capsys.readouterr().err.splitlines()
    assert err[0] == (
        "td3-invertedpendulum-1d-seed0: its Ray node died (NodeDiedError); submitted again "
        "(1 of 3), it resumes from its checkpoint"
    )
    assert len(err) == 1 + NODE_LOSS_RETRIES
    assert err[-1].endswith("submitted again (3 of 3), it resumes from its checkpoint")


@pytest.mark.cluster
def test_a_benchmark_survives_losing_the_node_running_it(tmp_path, monkeypatch):
    pytest.importorskip("torch", reason="training needs torch (rrls[train])")
    pytest.importorskip("ray", reason="the Ray backend needs `pip install rrls[ray]`")
    from ray.cluster_utils import Cluster

    local, out = tmp_path / "local", tmp_path / "ray"
    logs = {name: tmp_path / f"{name}.log" for name in ("local", "ray")}
    # the nodes' workers import this checkout's rrls, as the drivers do (run from REPO); the
    # cluster's own temporary directory: its address is written there, not in /tmp/ray where
    # `ray.init()` elsewhere on this machine would find it and join it (short: Ray's socket
    # paths must fit in 107 bytes)
    monkeypatch.setenv("PYTHONPATH", os.pathsep.join([str(REPO), os.environ.get("PYTHONPATH", "")]))
    temp = tempfile.mkdtemp(prefix="rrls-ray-", dir="/tmp")
    monkeypatch.setenv("RAY_TMPDIR", temp)
    drivers: dict[str, subprocess.Popen] = {}

    def start(name: str, *args: str) -> subprocess.Popen:
        with logs[name].open("w") as sink:
            drivers[name] = subprocess.Popen(
                [sys.executable, "-m", "rrls", *SMOKE, *args],
                cwd=REPO,
                stdout=sink,
                stderr=subprocess.STDOUT,
            )
        return drivers[name]

    cluster, held = None, None
    try:
        start("local", "--out", str(local), "--workers", "2")  # the reference, meanwhile
        head = {"num_cpus": 0, "include_dashboard": False}  # the driver's node: no runs
        cluster = Cluster(initialize_head=True, head_node_args=head)
        doomed = cluster.add_node(num_cpus=1)  # the only CPU: the first run starts here
        ray_args = ["--backend", "ray", "--ray-address", cluster.address]
        driver = start("ray", "--out", str(out), *ray_args)
        started = lambda: list(out.glob("runs/*/progress.json"))  # noqa: E731
        _wait(started, 300, "run started", driver)
        first = started()[0].parent
        cluster.add_node(num_cpus=2)  # the node left: the second run, then the first again
        _wait((first / "checkpoint.pt").exists, 300, f"checkpoint in {first.name}", driver)
        lost = json.loads((first / "progress.json").read_text())["pid"]
        t0 = time.monotonic()
        # the whole node at once: its worker is frozen first, or it may finish the short smoke
        # run and hand its result straight to the driver in the moment it outlives its raylet
        os.kill(lost, signal.SIGSTOP)
        cluster.remove_node(doomed, allow_graceful=False)
        with contextlib.suppress(ProcessLookupError):
            os.kill(lost, signal.SIGKILL)
        assert not (first / "result.json").exists(), "the run finished before its node died"
        # the lost run's hold on its directory outlives its process here, as a dead NFS client's
        # lock does until its lease runs out: the run submitted again waits for it
        held = _take(first, 60)
        assert json.loads((first / "progress.json").read_text())["pid"] == lost
        again = f"{first.name}: its Ray node died (NodeDiedError); submitted again (1 of 3)"
        _wait(lambda: again in logs["ray"].read_text(), 120, "resubmission", driver)
        time.sleep(5)
        assert json.loads((first / "progress.json").read_text())["pid"] == lost
        assert not (first / "error.txt").exists()
        held.__exit__(None, None, None)
        held = None
        for name, proc in drivers.items():
            assert proc.wait(timeout=600) == 0, logs[name].read_text()[-3000:]
        print(f"the benchmark finished {time.monotonic() - t0:.1f} s after the node died")
    finally:
        if held is not None:
            held.__exit__(None, None, None)
        for proc in drivers.values():
            if proc.poll() is None:
                proc.kill()
                proc.wait()
        if cluster is not None:
            cluster.shutdown()
        shutil.rmtree(temp, ignore_errors=True)

    # every run once, finished once, the lost one by another process than the one it died in
    assert {p.name for p in (out / "runs").iterdir()} == RUNS
    for run in RUNS:
        files = {p.name for p in (out / "runs" / run).iterdir()}
        assert "result.json" in files and not {"error.txt", "checkpoint.pt"} & files
    assert json.loads((first / "progress.json").read_text())["pid"] != lost

    # the numbers of the local run: every evaluation episode, curve, policy and summary cell
    for table in ("evaluations", "curves", "dynamic", "runs"):
        mine, theirs = (
            pd.read_parquet(root / "results" / f"{table}.parquet")
            .drop(columns=["steps_per_second"], errors="ignore")  # the machine's speed
            .sort_values(["algorithm", "seed"], kind="stable")
            .reset_index(drop=True)
            for root in (out, local)
        )
        pd.testing.assert_frame_equal(mine, theirs)
    for run, name in [(run, "policy.npz") for run in RUNS] + [(RUNS_RARL, "adversary.npz")]:
        with (
            np.load(out / "runs" / run / name) as mine,
            np.load(local / "runs" / run / name) as theirs,
        ):
            assert mine.files == theirs.files
            for k in set(mine.files) - {"header"}:  # (the header names the run's directory)
                assert np.array_equal(mine[k], theirs[k]), (run, name, k)
    summary, reference = (
        json.loads((root / "report" / "summary.json").read_text())["results"]
        for root in (out, local)
    )
    assert summary == reference


def test_the_protocol_page_states_what_is_retried():
    from rrls.benchmark.backends import LOCK_WAIT_S, NODE_LOSS_RETRIES

    page = (REPO / "docs" / "protocol.md").read_text()
    section = page[page.index("### When a node is lost") :]
    section = " ".join(section[: section.index("\n## ")].split())
    assert f"up to {NODE_LOSS_RETRIES} times" in section
    assert f"(1 of {NODE_LOSS_RETRIES})" in section
    assert f"at most {LOCK_WAIT_S / 60:g} minutes" in section
