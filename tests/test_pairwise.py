"""Pairwise comparisons: Welch's test per pair, Holm's correction over the pairs, Hedges' g;
checked against SciPy and an independent Holm procedure, on random samples and on the shipped
HalfCheetah reference, and the paper's orderings judged by the corrected test."""

from __future__ import annotations

import csv
import itertools
import json
from pathlib import Path

import numpy as np
import pytest

from rrls.report.pairwise import ALPHA, compare, holm, judge_paper, pairwise
from rrls.report.writer import paper_results

stats = pytest.importorskip("scipy.stats")
ROOT = Path(__file__).resolve().parents[1]
ALGOS = ("td3", "dr", "m2td3", "rarl", "nrmdp")


def shipped(name: str, metric: str) -> dict[str, list[float]]:
    """Per-seed values of a shipped reference's runs (its report's per-run table)."""
    out: dict[str, list[float]] = {}
    with open(ROOT / "docs" / "results" / name / "tables" / "per_run.csv", newline="") as f:
        for row in csv.DictReader(f):
            out.setdefault(row["algorithm"], []).append(float(row[metric]))
    return {a: out[a] for a in ALGOS if a in out}


def holm_rejects(p: np.ndarray, alpha: float) -> np.ndarray:
    """Holm's step-down procedure as its paper states it (independent of ``holm``)."""
    order = np.argsort(p)
    reject = np.zeros(len(p), dtype=bool)
    for k, i in enumerate(order):
        if p[i] > alpha / (len(p) - k):
            break
        reject[i] = True
    return reject


@pytest.mark.parametrize("seed", range(20))
def test_holm_rejects_exactly_what_the_step_down_procedure_rejects(seed):
    rng = np.random.default_rng(seed)
    p = rng.uniform(0, 0.1, size=rng.integers(1, 12)) ** rng.uniform(0.5, 2)
    adjusted = np.asarray(holm(p))
    for alpha in (0.01, 0.05, 0.1):
        assert ((adjusted < alpha) == holm_rejects(p, alpha)).all() or np.isclose(
            adjusted, alpha
        ).any()
    assert (adjusted >= p).all() and (adjusted <= 1).all()


@pytest.mark.parametrize("metric", ["worst_case", "average_case"])
def test_every_pair_of_the_halfcheetah_reference_matches_scipy(metric):
    values = shipped("halfcheetah", metric)
    rows = pairwise(values)
    assert len(rows) == 10
    for row in rows:
        x, y = np.asarray(values[row["a"]]), np.asarray(values[row["b"]])
        test = stats.ttest_ind(x, y, equal_var=False)
        ci = test.confidence_interval(0.95)
        assert row["p"] == pytest.approx(test.pvalue, rel=1e-12)
        assert row["ci95"] == pytest.approx([ci.low, ci.high], rel=1e-12)
        assert row["diff"] == pytest.approx(x.mean() - y.mean(), rel=1e-12)
        pooled = np.sqrt((4 * x.var(ddof=1) + 4 * y.var(ddof=1)) / 8)
        assert row["hedges_g"] == pytest.approx((x.mean() - y.mean()) / pooled * (1 - 3 / 31))
    assert [r["p_holm"] for r in rows] == holm([r["p"] for r in rows])


def test_halfcheetah_worst_case_rarl_below_td3_is_not_a_contradiction_after_correction():
    """Uncorrected, RARL < TD3 (the paper: RARL > TD3) at p = 0.045; over the ten pairs Holm
    resolves none of the worst-case orderings, DR > TD3 (p = 0.010) included."""
    rows = {(r["a"], r["b"]): r for r in pairwise(shipped("halfcheetah", "worst_case"))}
    assert rows["td3", "rarl"]["p"] == pytest.approx(0.045, abs=5e-4)
    assert rows["td3", "dr"]["p"] == pytest.approx(0.010, abs=5e-4)
    assert all(r["p_holm"] >= ALPHA for r in rows.values())
    judged = judge_paper(list(rows.values()), paper_results(), "halfcheetah", "worst_case")
    assert {j["verdict"] for j in judged} == {"unresolved"}
    flagged = [(j["hi"], j["lo"]) for j in judged if j["paper_says_not_significant"]]
    assert flagged == [("dr", "m2td3")]


def test_halfcheetah_average_case_orderings_judged_by_the_corrected_test():
    rows = pairwise(shipped("halfcheetah", "average_case"))
    judged = judge_paper(rows, paper_results(), "halfcheetah", "average_case")
    verdicts = {(j["hi"], j["lo"]): j["verdict"] for j in judged}
    assert verdicts.pop(("m2td3", "td3")) == "unresolved"
    assert set(verdicts.values()) == {"reproduced"}


def test_the_papers_own_numbers_are_tested_with_its_ten_seeds():
    paper = paper_results()
    for metric in ("worst_case", "average_case"):
        table = f"raw_{metric}"
        rows = pairwise({a: [0.0, 1.0] for a in ALGOS})  # any rows: the pairs
        for j in judge_paper(rows, paper, "halfcheetah", metric):
            (ma, sa), (mb, sb) = (
                paper[table][j["hi"]]["halfcheetah"],
                paper[table][j["lo"]]["halfcheetah"],
            )
            expected = stats.ttest_ind_from_stats(ma, sa, 10, mb, sb, 10, equal_var=False)
            assert j["paper_p"] == pytest.approx(expected.pvalue)
            assert ma > mb  # hi is the paper's higher mean


def test_too_few_seeds_give_no_test_and_no_verdict():
    row = compare([1.0], [2.0, 3.0])
    assert row["p"] is None and row["ci95"] is None and row["diff"] == pytest.approx(-1.5)
    rows = pairwise({"a": [1.0], "b": [2.0, 3.0], "c": [5.0, 6.0, 7.0]})
    assert [r["verdict"] is None for r in rows] == [True, True, False]


def test_the_report_writes_the_pairwise_section_and_tables(tmp_path):
    from rrls.benchmark.store import build_store
    from rrls.evaluation import BatchInvariant
    from rrls.report.writer import make_report
    from rrls.submissions import submit
    from rrls.submissions.steps import create_benchmark

    root = tmp_path / "bench"
    create_benchmark(root, "smoke", ("invertedpendulum",))
    gains = {"good": [(1.0, 5.0, 0.3, 1.0), (1.1, 5.0, 0.3, 1.0)], "bad": [(0.0,) * 4] * 2}
    for algo, seeds in gains.items():
        for seed, g in enumerate(seeds):
            k = np.asarray(g)
            policy = BatchInvariant(lambda obs, k=k: np.clip((obs @ k)[:, None], -3, 3))
            submit(root, algo, "invertedpendulum", seed, policy, workers=1, progress=False)
    build_store(root)
    make_report(root, plots=False)
    text = (root / "report" / "report.md").read_text()
    assert "## Pairwise comparisons (Welch, Holm-corrected)" in text
    summary = json.loads((root / "report" / "summary.json").read_text())
    (row,) = summary["pairwise"]["invertedpendulum"]["worst_case"]
    assert row["p_holm"] == row["p"]  # one pair: nothing to correct
    assert (root / "report" / "tables" / "pairwise_worst_case.tex").exists()
    with open(root / "report" / "tables" / "pairwise.csv", newline="") as f:
        assert len(list(csv.DictReader(f))) == 2  # one pair x two scores
    assert list(itertools.chain(summary["paper_orderings"])) == []  # the 1D set: not the paper's
