"""Budgets on the record: a submission records the training budget its submitter declares (or
its policy records), the report prints each source's budget beside the benchmark's and marks the
rows whose budget differs; step counts read 30000, 1e4 or 100k in every command."""

from __future__ import annotations

import argparse
import json
import re
from pathlib import Path

import numpy as np
import pytest

from rrls.argtypes import MAX_STEPS, step_count
from rrls.submissions.steps import SubmitError, create_benchmark, submit


def zeros(obs):
    return np.zeros((len(obs), 1))


@pytest.mark.parametrize(
    "text, value", [("30000", 30000), ("30_000", 30000), ("1e4", 10000), ("100k", 100_000),
                    ("1.5M", 1_500_000), ("0", 0)],
)  # fmt: skip
def test_step_counts_read_as_people_write_them(text, value):
    assert step_count(text) == value


@pytest.mark.parametrize("text", ["1.5", "-5", "x", "inf", "nan", "1e13", "0.0005k"])
def test_a_step_count_that_is_not_one_names_the_valid_range(text):
    with pytest.raises(argparse.ArgumentTypeError, match=re.escape(f"from 0 to {MAX_STEPS:.0e}")):
        step_count(text)


def test_train_and_benchmark_accept_1e4_and_100k():
    from rrls.cli import build_parser

    bench = build_parser(False).parse_args(["benchmark", "--out", "b", "--steps", "1e4"])
    assert bench.steps == 10_000
    pytest.importorskip("torch")
    train = build_parser(True).parse_args(
        ["train", "--algo", "td3", "--task", "hopper", "--steps", "100k", "--eval-every", "5k"]
    )
    assert (train.steps, train.eval_every) == (100_000, 5_000)


def test_submit_records_the_declared_budget_and_the_report_marks_a_different_one(tmp_path):
    from rrls.benchmark.store import build_store
    from rrls.report.writer import make_report

    bench = tmp_path / "bench"
    create_benchmark(bench, "smoke", ("invertedpendulum",))
    with pytest.raises(SubmitError, match="--steps must be a whole number >= 1"):
        submit(bench, "short", "invertedpendulum", 0, zeros, workers=1, steps=0)
    submit(bench, "same", "invertedpendulum", 0, zeros, workers=1, steps=300)
    budget = {"gpu hours": "2"}
    submit(bench, "short", "invertedpendulum", 0, zeros, workers=1, steps=200, budget=budget)
    submit(bench, "silent", "invertedpendulum", 0, zeros, workers=1)
    result = json.loads(
        (bench / "runs" / "short-invertedpendulum-1d-seed0" / "result.json").read_text()
    )
    assert result["steps"] == 200
    assert result["submitted"]["budget"] == {"steps": 200, "declared_by": "submitter", **budget}
    build_store(bench)
    text = make_report(bench, plots=False).read_text()
    assert "## Budgets" in text and "this benchmark's protocol: 300." in text
    assert "300 training steps per run trained here (other sources: Budgets below)" in text
    assert "| same (submitted) | 300 | – | declared by submitter |" in text
    assert "| short (submitted)‡ | 200 | gpu hours 2 | declared by submitter; **differs** |" in text
    assert "| silent (submitted)‡ | not stated | – | declared by nobody; **differs** |" in text
    assert "short (submitted)‡" in text and "same (submitted)‡" not in text
    tex = (bench / "report" / "tables" / "raw_worst_case.tex").read_text()
    assert "short (submitted)$^{\\ddagger}$ &" in tex
    assert "$^{\\ddagger}$ another training budget" in tex  # the caption says what it means


def test_a_report_points_to_budgets_only_where_it_has_them():
    """A report without other sources (submitted runs, a reference) has no Budgets section, and
    its opening line does not point to one: each shipped report, as its writer made it."""
    root = Path(__file__).resolve().parent.parent / "docs" / "results"
    reports = sorted(root.rglob("report.md"))
    assert len(reports) >= 5
    for report in reports:
        text = report.read_text()
        assert ("Budgets below" in text) == ("## Budgets" in text), report
