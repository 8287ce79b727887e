"""``rrls report`` gives in- and out-of-distribution worst/average case when runs had a split."""

from __future__ import annotations

import pandas as pd
import pytest

from rrls.cli import main
from rrls.evaluation.metrics import split_run_scores as split_scores
from rrls.report.writer import summarise


def _store(root, with_split: bool = True):
    """Two seeds of TD3 on hopper, four mesh points each: points 0-1 in, 2-3 out of distribution."""
    rows = []
    returns = {0: [10.0, 20.0, 1.0, 3.0], 1: [30.0, 40.0, 5.0, 9.0]}
    for seed, rets in returns.items():
        for point, ret in enumerate(rets):
            for episode, noise in enumerate((-1.0, 1.0)):
                row = dict(algorithm="td3", task="hopper", uncertainty="2d", seed=seed, steps=10)
                row.update(point=point, episode=episode, **{"return": ret + noise})
                if with_split:
                    row["in_distribution"] = point < 2
                rows.append(row)
    results = root / "results"
    results.mkdir(parents=True)
    pd.DataFrame(rows).to_csv(results / "evaluations.csv", index=False)
    pd.DataFrame(columns=["algorithm", "task", "seed", "episode", "return"]).to_csv(
        results / "dynamic.csv", index=False
    )
    pd.DataFrame(
        [dict(algorithm="td3", task="hopper", uncertainty="2d", seed=s, steps=10) for s in (0, 1)]
    ).to_csv(results / "runs.csv", index=False)
    pd.DataFrame(columns=["algorithm", "task", "seed", "step"]).to_csv(
        results / "curves.csv", index=False
    )


def test_report_splits_scores_in_and_out_of_distribution(tmp_path):
    _store(tmp_path)
    table = split_scores(pd.read_csv(tmp_path / "results" / "evaluations.csv"))
    assert table.set_index("seed")[["worst_case_id", "average_case_ood"]].to_dict("index") == {
        0: {"worst_case_id": 10.0, "average_case_ood": 2.0},
        1: {"worst_case_id": 30.0, "average_case_ood": 7.0},
    }
    cell = summarise(tmp_path)["results"]["hopper"]["td3"]
    assert cell["split"]["worst_case_id"]["mean"] == pytest.approx(20.0)
    assert cell["split"]["average_case_id"]["mean"] == pytest.approx(25.0)
    assert cell["split"]["worst_case_ood"]["mean"] == pytest.approx(3.0)
    assert cell["split"]["average_case_ood"]["mean"] == pytest.approx(4.5)
    assert cell["worst_case"]["mean"] == pytest.approx(3.0)  # the whole mesh, as before
    assert main(["report", str(tmp_path), "--no-plots"]) == 0
    md = (tmp_path / "report" / "report.md").read_text()
    assert "## In and out of distribution" in md
    # two seeds: every cell carries the few-seeds mark, and the report says what it means
    row = "| hopper | TD3 | 20.00 ± 10.00† | 25.00 ± 10.00† | 3.00 ± 2.00† | 4.50 ± 2.50† |"
    assert row in md and "† fewer than 3 seeds" in md


def test_report_without_a_split_is_unchanged(tmp_path):
    _store(tmp_path, with_split=False)
    assert "split" not in summarise(tmp_path)["results"]["hopper"]["td3"]
    assert main(["report", str(tmp_path), "--no-plots"]) == 0
    assert "In and out of distribution" not in (tmp_path / "report" / "report.md").read_text()
