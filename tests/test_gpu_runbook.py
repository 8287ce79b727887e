"""The GPU runbook, checked without a GPU: every row is on disk the moment it is measured, a step
past its timeout is killed (its children too) and leaves a 'timed out' row while the earlier
rows stay and the next step runs, a runbook killed mid-step keeps what it wrote, rates come from
the loop's own clock, the estimate marks where each figure came from, and the CPU dry run of the
whole command measures, refuses and estimates."""

from __future__ import annotations

import importlib.util
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

#: the long end-to-end tier (.ci/run runs it after the default suite)
pytestmark = pytest.mark.e2e

ROOT = Path(__file__).resolve().parents[1]
PY = sys.executable


def _runbook():
    spec = importlib.util.spec_from_file_location("gpu_runbook", ROOT / "benchmarks/gpu_runbook.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules["gpu_runbook"] = module
    spec.loader.exec_module(module)
    return module


def _jsonl(path: Path) -> list[dict]:
    return [json.loads(line) for line in path.read_text().splitlines()]


def _state(pid: int) -> str:
    """A process's state letter (R, S, Z...), or "gone"."""
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except (FileNotFoundError, ProcessLookupError):
        return "gone"


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="reads /proc")
def test_rows_are_written_as_measured_and_a_timed_out_step_leaves_the_rest(tmp_path):
    runbook = _runbook()
    rows = runbook.Rows(tmp_path / "out")
    jsonl, pids = rows.jsonl, tmp_path / "child.pid"
    # the second step reads the file while the runbook runs: the first row is already there
    check = (
        f"import json, sys; rows = [json.loads(x) for x in open({str(jsonl)!r})]; "
        "sys.exit(0 if [r['k'] for r in rows] == [1] and rows[0]['status'] == 'ok' else 3)"
    )
    # a step that outlives its timeout, with a child of its own (as rrls train's workers)
    hang = (
        "import subprocess, sys, time; "
        "c = subprocess.Popen([sys.executable, '-c', 'import time; time.sleep(120)']); "
        f"open({str(pids)!r}, 'w').write(str(c.pid)); time.sleep(120)"
    )
    steps = [
        runbook.Step("loop", "td3", "hopper", 1, [PY, "-c", "pass"]),
        runbook.Step("loop", "td3", "hopper", 2, [PY, "-c", check]),
        runbook.Step("baseline", "rarl", "hopper", 10, refused="no twin path"),
        runbook.Step("loop", "td3", "hopper", 3, [PY, "-c", hang]),
        runbook.Step("loop", "td3", "hopper", 4, [PY, "-c", "import sys; sys.exit('boom')"]),
        runbook.Step("loop", "td3", "hopper", 5, [PY, "-c", "pass"]),
    ]
    start = time.monotonic()
    runbook.run_steps(steps, rows, deadline=time.monotonic() + 600, step_timeout=3)
    assert time.monotonic() - start < 60  # the 120 s step was cut at 3 s
    written = _jsonl(jsonl)
    assert written == rows.rows and [r["k"] for r in written] == [1, 2, 10, 3, 4, 5]
    status = [r["status"] for r in written]
    assert status[:2] == ["ok", "ok"] and status[2] == "refused: no twin path"
    assert status[3] == "timed out after 3 s" and status[4] == "failed: boom"
    assert status[5] == "ok"  # the step after the timeout still ran
    time.sleep(0.5)
    assert _state(int(pids.read_text())) in ("gone", "Z", "X")  # its child was killed too
    md = (tmp_path / "out" / "rows.md").read_text()
    assert "K=3: timed out after 3 s" in md and "K=2: ok" in md
    # a deadline already past: the next step is a 'skipped' row, no process starts
    runbook.run_steps(steps[:1], rows, deadline=time.monotonic(), step_timeout=3)
    assert _jsonl(jsonl)[-1]["status"].startswith("skipped: 0 s left")


def test_a_runbook_killed_mid_step_keeps_its_earlier_rows(tmp_path):
    out = tmp_path / "out"
    script = f"""
import importlib.util, sys, time
spec = importlib.util.spec_from_file_location("rb", {str(ROOT / "benchmarks/gpu_runbook.py")!r})
rb = importlib.util.module_from_spec(spec); sys.modules["rb"] = rb; spec.loader.exec_module(rb)
py = sys.executable
steps = [rb.Step("loop", "td3", "hopper", 1, [py, "-c", "pass"]),
         rb.Step("loop", "td3", "hopper", 32, [py, "-c", "import time; time.sleep(120)"])]
rb.run_steps(steps, rb.Rows(rb.Path({str(out)!r})), time.monotonic() + 600, 300)
"""
    proc = subprocess.Popen([PY, "-c", script], start_new_session=True)
    jsonl = out / "rows.jsonl"
    try:
        for _ in range(600):  # the first row, then the 120 s step: the lease ends mid-step
            if jsonl.exists() and jsonl.read_text().count("\n") == 1:
                break
            time.sleep(0.1)
        os.killpg(proc.pid, signal.SIGKILL)
    finally:
        proc.wait()
    rows = _jsonl(jsonl)
    assert [(r["k"], r["status"]) for r in rows] == [(1, "ok")]


def test_the_rate_is_the_loops_own_clock_between_episode_ends(tmp_path):
    runbook = _runbook()
    scalars = tmp_path / "scalars.csv"
    lines = ["step,metric,value", "100,charts/steps_per_second,1000.0"]  # 0.1 s
    lines += ["1200,charts/episode_return,5.0", "1200,charts/steps_per_second,600.0"]  # 2 s
    lines += ["2000,charts/steps_per_second,500.0"]  # 4 s
    scalars.write_text("\n".join(lines) + "\n")
    per_run, window = runbook.rate_from_scalars(scalars, after=1000)
    assert window == (1200, 2000) and per_run == pytest.approx(800 / 2.0)
    # fewer than two episode ends after the warm-up: the whole run's rate
    assert runbook.rate_from_scalars(scalars, after=1500) == (500.0, (0, 2000))


def test_the_estimate_marks_measured_extrapolated_and_stored_cells():
    runbook = _runbook()

    def row(algo, task, rate, k=10):
        return {"kind": "baseline", "algo": algo, "task": task, "k": k, "status": "ok"} | {
            "env_steps_per_s": rate
        }

    rows = [
        row("td3", "hopper", 2000.0),
        row("dr", "hopper", 1500.0),
        row("dr", "halfcheetah", 1700.0),
    ]
    rows += [row("td3", "hopper", 9000.0, k=32)]  # another K: not the paper's packing
    rows += [
        {"kind": "baseline", "algo": "rarl", "task": "hopper", "k": 10, "status": "refused: x"}
    ]
    est = runbook.paper_estimate(rows)
    cells = est["cells"]
    assert cells["td3/hopper"] == cells["dr/hopper"] == cells["dr/halfcheetah"] == "measured"
    assert cells["td3/walker"] == cells["dr/ant"] == "extrapolated"  # twin tasks not measured
    assert cells["td3/humanoidstandup"] == "stored"  # no twin for it
    assert cells["rarl/hopper"] == cells["m2td3/hopper"] == "stored"  # refused, no row
    assert len(cells) == 25 and est["sources"] == "3 measured, 5 extrapolated, 17 stored"
    faster = runbook.paper_estimate(
        [r | {"env_steps_per_s": 10 * r.get("env_steps_per_s", 1)} for r in rows]
    )
    assert faster["wall_h"] < est["wall_h"] and faster["stored_wall_h"] == est["stored_wall_h"]


def test_the_dry_run_measures_refuses_and_estimates_on_a_cpu(tmp_path):
    pytest.importorskip("torch")
    from rrls.algorithms import paper_five
    from rrls.twin.catalog import not_on_twin

    runbook = _runbook()
    out = tmp_path / "out"
    argv = [str(out), "--device", "cpu", "--simulator", "mujoco", "--tiny", "--step-timeout", "300"]
    assert runbook.main(argv) == 0
    rows = _jsonl(out / "rows.jsonl")
    assert rows[0]["kind"] == "machine" and rows[0]["torch"] and rows[0]["cuda"] is False
    trained = [r for r in rows if r["kind"] in ("loop", "baseline") and "command" in r]
    assert [(r["kind"], r["algo"], r["k"]) for r in trained] == [
        ("loop", "td3", 1),
        ("baseline", "dr", 2),
    ]
    for r in trained:
        assert r["status"] == "ok" and r["env_steps_per_s"] > 0, r
        assert "--simulator mujoco" in r["command"] and "--seeds 0-" in r["command"]
    refused = {r["algo"]: r["status"] for r in rows if r.get("status", "").startswith("refused")}
    assert set(refused) == {a for a in paper_five() if not_on_twin(a)}
    for algo, status in refused.items():
        assert status == f"refused: the Warp twin does not train {algo}: {not_on_twin(algo)}"
    assert rows[-1]["kind"] == "estimate" and rows[-1]["cells"]["dr/hopper"] == "measured"
    assert "estimate (paper, K = 2)" in (out / "rows.md").read_text()


def test_the_plan_puts_the_most_wanted_rows_first_and_refuses_without_a_process(monkeypatch):
    import argparse

    import rrls.twin.catalog

    runbook = _runbook()
    monkeypatch.setattr(rrls.twin.catalog, "not_on_twin", lambda a: "no" if a == "nrmdp" else None)
    args = argparse.Namespace(ks=runbook.KS, pack=10, tasks=runbook.TASKS, algos=None)
    args.__dict__.update(steps=2000, starts=500, window_after=1000, device="cuda", simulator="warp")
    steps = runbook.plan(args, Path("/tmp/x"))
    order = [(s.kind, s.task, s.algo, s.k) for s in steps]
    five = ("td3", "dr", "rarl", "nrmdp", "m2td3")
    assert order[:4] == [("loop", "hopper", "td3", k) for k in (1, 32, 128, 256)]
    assert sorted(order[4:9]) == sorted(("baseline", "hopper", a, 10) for a in five)
    assert order[9] == ("shared", "hopper", "+".join(five), 10) and steps[9].total == 50
    assert sorted(order[10:15]) == sorted(("baseline", "halfcheetah", a, 10) for a in five)
    assert order[15] == ("shared", "halfcheetah", "+".join(five), 10)
    assert order[16:] == [("loop", "halfcheetah", "td3", k) for k in (1, 32, 128, 256)]
    for s in steps:
        if s.kind == "shared":  # the five on one twin: a script, run 0 in OUT/seed0
            assert s.command[1].endswith("benchmarks/twin_shared.py") and "--k 10" in " ".join(
                s.command
            )
        elif s.algo == "nrmdp":
            assert s.command is None and s.refused == "the Warp twin does not train nrmdp: no"
        else:
            assert s.refused is None and s.command[2:4] == ["rrls", "train"]
            assert "--simulator warp" in " ".join(s.command) and f"--seeds 0-{s.k - 1}" in " ".join(
                s.command
            )


def test_shared_twin_rows_give_the_protocol_as_a_warp_benchmark_packs_it():
    """A ``shared`` row (the five baselines on one twin) times each task's algorithms as one
    group: measured for its task and run count, extrapolated (its per-run rate) elsewhere."""
    runbook = _runbook()
    base = {"kind": "baseline", "task": "hopper", "k": 10, "status": "ok"}
    rows = [base | {"algo": a, "env_steps_per_s": 2000.0} for a in ("td3", "dr")]
    alone = runbook.paper_estimate(rows)
    assert "shared_wall_h" not in alone
    shared = {"kind": "shared", "algo": "td3+dr+rarl+nrmdp+m2td3", "task": "hopper", "k": 10}
    shared |= {"status": "ok", "per_run": 100.0, "runs": 50, "env_steps_per_s": 5000.0}
    est = runbook.paper_estimate([*rows, shared])
    assert est["wall_h"] == alone["wall_h"]  # the per-cell estimate is unchanged
    assert 0 < est["shared_wall_h"] and est["shared_measured"] is False  # other tasks: held
    rate = runbook.shared_rate([shared])
    assert rate("hopper", 50) == (5000.0, True) and rate("walker", 20) == (2000.0, False)
    faster = runbook.paper_estimate([*rows, shared | {"per_run": 200.0}])
    assert faster["shared_wall_h"] < est["shared_wall_h"]
    assert "a task's algorithms sharing each twin step" in runbook.line(est)
    assert runbook.shared_rate([shared | {"status": "failed: x"}]) is None


@pytest.mark.warp
def test_the_shared_step_trains_the_five_on_one_twin_and_reads_run_0s_clock(tmp_path):
    """The runbook's ``shared`` step on warp's CPU device, at the smallest sizes: the paper's
    five baselines, one seed each, on one Hopper twin (``benchmarks/twin_shared.py``), its rate
    run 0's times the five runs."""
    pytest.importorskip("warp")
    pytest.importorskip("mujoco_warp")
    import argparse

    runbook = _runbook()
    args = argparse.Namespace(ks=(), pack=1, tasks=("hopper",), algos=None, steps=60, starts=20)
    args.__dict__.update(window_after=20, device="cpu", simulator="warp")
    shared = [s for s in runbook.plan(args, tmp_path) if s.kind == "shared"]
    assert len(shared) == 1 and shared[0].total == 5
    row = runbook.run_step(shared[0], timeout=600)
    assert row["status"] == "ok", row
    assert row["runs"] == 5 and row["env_steps_per_s"] == pytest.approx(5 * row["per_run"])
    made = sorted(p.name for p in shared[0].runs.iterdir())
    assert made == ["dr-seed0", "m2td3-seed0", "nrmdp-seed0", "rarl-seed0", "seed0"]
    assert all((shared[0].runs / name / "policy.npz").exists() for name in made)
