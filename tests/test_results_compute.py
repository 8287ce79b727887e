"""What the pages say a run cost and where it trained: every execution of a resumed run is
counted from its TensorBoard files (``benchmarks/collect_runs.py``), an execution that only
evaluated is listed with its span, and a run trained on two CPU kinds names both in order."""

from __future__ import annotations

import sys
from pathlib import Path

import pandas as pd

ROOT = Path(__file__).resolve().parent.parent
RESULTS = ROOT / "docs" / "results"
sys.path.insert(0, str(ROOT / "benchmarks"))

import page_runs  # noqa: E402


def test_a_resumed_runs_cost_counts_every_execution(tmp_path, monkeypatch):
    # two executions, each with its TensorBoard file; result.json times the second only
    import json
    import os
    import time

    import collect_runs
    from torch.utils.tensorboard import SummaryWriter

    run = tmp_path / "bench" / "runs" / "td3-hopper-3d-seed0"
    for began, ended in ((1000.0, 1500.0), (2000.0, 2600.0)):
        monkeypatch.setattr(time, "time", lambda began=began: began)  # the file's first event
        writer = SummaryWriter(str(run / "tb"))
        for wall in (began, ended):
            writer.add_scalar("charts/episode_return", 1.0, int(wall), walltime=wall)
        writer.close()
    monkeypatch.undo()
    (run / "result.json").write_text(json.dumps({"seconds": 750.0}))
    os.utime(run / "result.json", (2700.0, 2700.0))  # written at 2 700: its clock began at 1 950
    assert len(list((run / "tb").glob("events.*"))) == 2
    dest = tmp_path / "shipped"
    assert collect_runs.executions(run, dest / collect_runs.EXECUTIONS)
    assert not collect_runs.executions(run, dest / collect_runs.EXECUTIONS)  # unchanged
    rows = pd.read_csv(dest / collect_runs.EXECUTIONS)
    assert list(rows["in_result"]) == [0, 1] and list(rows["started"]) == [1000.0, 2000.0]
    assert list(rows["ended"]) == [1500.0, 2600.0] and list(rows["last_step"]) == [1500, 2600]
    # each file's first logged step, not its header's 0
    assert list(rows["first_step"]) == [1000, 2000]
    (dest / "result.json").write_text((run / "result.json").read_text())
    assert collect_runs.run_seconds(dest) == (750.0 + 500.0, 2)
    (dest / collect_runs.EXECUTIONS).unlink()
    assert collect_runs.run_seconds(dest) == (750.0, 0)  # not known: result.json alone


def test_an_execution_that_only_evaluated_is_listed_with_its_span(tmp_path, monkeypatch):
    # a run resumed from a checkpoint at its budget trains nothing and writes no event file:
    # its last execution is result.json's own span, at the final step
    import json
    import os
    import time

    import collect_runs
    from torch.utils.tensorboard import SummaryWriter

    run = tmp_path / "runs" / "td3-hopper-3d-seed0"
    monkeypatch.setattr(time, "time", lambda: 1000.0)
    writer = SummaryWriter(str(run / "tb"))
    for wall in (1000.0, 1500.0):
        writer.add_scalar("charts/episode_return", 1.0, int(wall), walltime=wall)
    writer.close()
    monkeypatch.undo()
    (run / "run.json").write_text(json.dumps({"steps": 1500}))
    (run / "result.json").write_text(json.dumps({"seconds": 300.0}))
    os.utime(run / "result.json", (2300.0, 2300.0))  # evaluated from 2 000 to 2 300
    dest = tmp_path / "shipped" / collect_runs.EXECUTIONS
    assert collect_runs.executions(run, dest)
    rows = pd.read_csv(dest)
    assert list(rows["in_result"]) == [0, 1] and list(rows["started"]) == [1000.0, 2000.0]
    assert list(rows["ended"]) == [1500.0, 2300.0]
    assert (rows["first_step"].iloc[-1], rows["last_step"].iloc[-1]) == (1500, 1500)


def test_every_shipped_execution_list_names_the_one_result_json_times():
    import json

    for path in sorted(RESULTS.glob("*/runs/*/executions.csv")):
        rows = pd.read_csv(path)
        assert list(rows["in_result"]) == [0] * (len(rows) - 1) + [1], path
        assert (rows["ended"] >= rows["started"]).all() and rows["started"].is_monotonic_increasing
        last = rows.iloc[-1]
        seconds = json.loads((path.parent / "result.json").read_text())["seconds"]
        assert last.ended - last.started <= seconds, path  # its training, within its clock


def test_a_run_trained_on_two_cpu_kinds_names_both_in_order(tmp_path):
    # run.json's provenance.executions: the pages name every CPU kind a run trained on
    import json

    first = {"cores": 2, "cpu": "AMD EPYC", "simd": "X86_V4"}
    second = {"cores": 2, "cpu": "AMD EPYC", "simd": "X86_V3"}
    executions = [
        {"first_step": 0, "machine": None, "commit": None},
        {"first_step": 50_000, "machine": first, "commit": "a" * 40},
        {"first_step": 90_000, "machine": first, "commit": "b" * 40},
        {"first_step": 300_000, "machine": second, "commit": "b" * 40},
    ]
    for seed, listed in ((0, executions), (1, None)):
        run = tmp_path / "runs" / f"td3-hopper-3d-seed{seed}"
        run.mkdir(parents=True)
        result = {"algorithm": "td3", "seed": seed, "worst_case": 1.0, "average_case": 2.0}
        (run / "result.json").write_text(json.dumps({**result, "seconds": 60.0}))
        provenance = {"commit": "b" * 40, "machine": second}
        if listed:
            provenance["executions"] = listed
        (run / "run.json").write_text(json.dumps({"provenance": provenance}))
    rows = page_runs.runs(tmp_path).splitlines()[2:]
    assert [row.split(" | ")[2] for row in rows] == ["? → X86_V4 → X86_V3", "X86_V3"]
    assert page_runs.compute(tmp_path).endswith(
        "; 2-core AMD EPYC (X86_V3): 1 runs, unknown CPU then 2-core AMD EPYC (X86_V4) then "
        "2-core AMD EPYC (X86_V3): 1 runs.\n"
    )
