"""The GPU runbook's CPU dry run: every step of benchmarks/gpu_runbook.py on tiny budgets, so
the script a GPU machine runs first cannot rot while no GPU is lent to the project."""

from __future__ import annotations

import importlib.util
import json
import sys
from pathlib import Path

import pytest

pytest.importorskip("torch")
ROOT = Path(__file__).resolve().parents[1]


def _runbook():
    spec = importlib.util.spec_from_file_location("gpu_runbook", ROOT / "benchmarks/gpu_runbook.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules["gpu_runbook"] = module
    spec.loader.exec_module(module)
    return module


@pytest.mark.e2e
def test_the_gpu_runbook_runs_end_to_end_on_a_cpu(tmp_path):
    runbook = _runbook()
    out = tmp_path / "out"
    twin = bool(importlib.util.find_spec("warp") and importlib.util.find_spec("mujoco_warp"))
    argv = [str(out), "--device", "cpu", "--tiny"] + ([] if twin else ["--no-twin"])
    assert runbook.main(argv) == 0
    summary = json.loads((out / "runbook.json").read_text())
    assert summary["failed"] == [] and summary["steps"] in runbook.TINY_MENU
    book = (out / "runbook.md").read_text()
    steps = ["CUDA tests: ok", "GPU speed table: ok", "Hopper preset: ok", "report and"]
    if twin:
        steps += ["Warp twin: physics alone: ok", "Warp twin: the whole step: ok"]
        steps += ["Warp twin vs CPU MuJoCo: ok", "training on the twin: ok"]
        assert (out / "twin_check" / "check.csv").exists()
        assert "sim-to-sim" in (out / "twin_train.log").read_text()
    for step in steps:
        assert step in book, step
    bench = out / f"hopper-{summary['steps']}"
    reference = json.loads((bench / "reference.json").read_text())
    assert reference["provenance"]["preset"] == "hopper" and reference["rows"]
    assert (bench / "report" / "report.md").exists()
    # small files only: no checkpoint or replay buffer reaches OUT_DIR
    assert not [p for p in out.rglob("*") if "checkpoint" in p.name]
    assert all(p.stat().st_size <= runbook.SMALL for p in out.rglob("*") if p.is_file())


def test_the_budget_is_the_largest_that_fits():
    runbook = _runbook()
    menu = (1_000_000, 500_000, 200_000)
    assert runbook.choose(1e-3, 20, menu, eval_s=0) == 1_000_000  # 1 000 s
    assert runbook.choose(2e-3, 20, menu, eval_s=0) == 500_000  # 2 000 s > 1 200 s
    assert runbook.choose(2e-3, 20, menu, eval_s=300) == 200_000
    assert runbook.choose(1.0, 20, menu, eval_s=0) == 200_000  # nothing fits: the smallest
