"""The tutorials in docs/tutorials/ run, at smoke scale, as a user runs them (a subprocess)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

#: the long end-to-end tier (.ci/run runs it after the default suite)
pytestmark = pytest.mark.e2e

REPO = Path(__file__).resolve().parents[1]
TUTORIALS = REPO / "docs" / "tutorials"


def run_tutorial(name: str, *args: str, cwd: Path) -> str:
    env = {
        **os.environ,
        "PYTHONPATH": os.pathsep.join([str(REPO), os.environ.get("PYTHONPATH", "")]),
        "OMP_NUM_THREADS": "1",  # torch: one thread (the suite shares the machine's cores)
    }
    proc = subprocess.run(
        [sys.executable, str(TUTORIALS / name), *args],
        cwd=cwd,
        env=env,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    return proc.stdout


def test_tutorial_a_submits_an_sb3_agent_into_a_benchmark(tmp_path):
    pytest.importorskip("stable_baselines3")
    out = run_tutorial(
        "submit_sb3_agent.py", "--steps", "200", "--mesh", "2", "--episodes", "1", cwd=tmp_path
    )
    assert "submitted: bench-hopper/runs/sb3-sac-dr-hopper-3d-seed0" in out
    summary = json.loads((tmp_path / "bench-hopper" / "report" / "summary.json").read_text())
    assert summary["results"]["hopper"]["sb3-sac-dr"]["worst_case"]["n_seeds"] == 1
    assert summary["submitted"][0]["policy_kind"] == "sb3-zip"
    assert "| sb3-sac-dr (submitted)‡ |" in (tmp_path / "bench-hopper/report/report.md").read_text()


def test_tutorial_c_compares_a_method_with_the_shipped_quick_reference(tmp_path):
    pytest.importorskip("stable_baselines3")
    pytest.importorskip("scipy")
    out = run_tutorial("compare_with_references.py", "--steps", "200", "--seeds", "0", cwd=tmp_path)
    assert "the paper's tables are refused here" in out and "physics: 'paper' there" in out
    summary = json.loads((tmp_path / "bench-mine" / "report" / "summary.json").read_text())
    assert summary["normalisation"]["invertedpendulum"]["worst_case"] == "reference"
    assert summary["results"]["invertedpendulum"]["my-sac"]["normalised"]["worst_case"]
    assert summary["reference"]["label"].startswith("rrls quick preset")
    md = (tmp_path / "bench-mine" / "report" / "report.md").read_text()
    assert "## Reference: rrls quick preset" in md
