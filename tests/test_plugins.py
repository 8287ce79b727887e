"""A third-party learner (docs/examples/ddpg.py, written against the learner protocol alone)
works with every rrls tool: `rrls train --algo module:Learner`, groups of seeds, checkpoints and
resume, `rrls benchmark --algos` and its report; entry points name it too."""

from __future__ import annotations

import json
import os
import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import stopping_at

torch = pytest.importorskip("torch")

from rrls.cli import main  # noqa: E402

#: the long end-to-end tier (.ci/run runs it after the default suite)
pytestmark = pytest.mark.e2e

EXAMPLES = Path(__file__).resolve().parents[1] / "docs" / "examples"
SMALL = ["--hidden", "16", "16", "--batch-size", "32", "--learning-starts", "100"]


@pytest.fixture
def examples(monkeypatch):
    monkeypatch.syspath_prepend(str(EXAMPLES))
    path = os.pathsep.join([str(EXAMPLES), os.environ.get("PYTHONPATH", "")])
    monkeypatch.setenv("PYTHONPATH", path)  # benchmark workers are fresh processes
    yield
    sys.modules.pop("ddpg", None)


def _train(out, *extra):
    args = ["train", "--algo", "ddpg:Learner", "--task", "invertedpendulum", "--steps", "300"]
    args += ["--eval-every", "0", "--checkpoint-every", "70", "--out", str(out), *SMALL, *extra]
    return main(args)


def test_a_module_learner_trains_in_groups_and_resumes_exactly(tmp_path, examples):
    assert _train(tmp_path / "whole", "--seeds", "0-1") == 0
    with stopping_at(150):
        assert _train(tmp_path / "cut", "--seeds", "0-1") == 3
    assert _train(tmp_path / "cut", "--seeds", "0-1", "--resume") == 0
    for seed in (0, 1):
        a, b = (np.load(tmp_path / d / f"seed{seed}" / "policy.npz") for d in ("whole", "cut"))
        assert all(np.array_equal(a[k], b[k]) for k in a.files if k != "header")
    run = json.loads((tmp_path / "whole" / "seed1" / "run.json").read_text())
    assert run["algorithm"] == "ddpg:Learner" and run["steps"] == 300


def test_unknown_module_learners_are_one_line_errors(tmp_path, capsys):
    assert _train(tmp_path / "x", "--algo", "no_such_module:Learner") == 2
    err = capsys.readouterr().err.strip()
    assert "no_such_module" in err and "\n" not in err


def test_a_module_learner_in_the_benchmark_and_its_report(tmp_path, examples):
    from rrls.benchmark.grid import make_spec
    from rrls.benchmark.runner import benchmark
    from rrls.report import make_report

    spec = make_spec("smoke", algos="td3,ddpg:Learner", seeds=1)
    assert benchmark(tmp_path, spec, 2, report=make_report) == 0
    summary = json.loads((tmp_path / "report" / "summary.json").read_text())
    assert {"td3", "ddpg:Learner"} <= set(next(iter(summary["results"].values())))


def test_a_plugin_registered_after_import_is_named_by_its_row():
    """Display names are read from the table at use, not a snapshot taken at import."""
    from rrls.algorithms import ALGORITHMS, AlgorithmInfo, register_algorithm
    from rrls.report import names, tables

    assert names.display_name("late_algo") == "late_algo"
    register_algorithm(AlgorithmInfo("late_algo", "Late-Algo", "mypkg.late:Learner"))
    try:
        assert names.display_name("late_algo") == "Late-Algo"
        assert tables.label({"labels": {}}, "late_algo").startswith("Late-Algo")
    finally:
        del ALGORITHMS["late_algo"]
