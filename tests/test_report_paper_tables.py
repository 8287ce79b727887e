"""The paper's own numbers through ``rrls report``: a store with exactly its per-seed means
and stds gives back its normalised Tables 4-5 (and its known erratum), Table 6, the missing
cells by name, and bootstrap intervals that a seed reproduces."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from rrls.cli import main
from rrls.report import stats
from rrls.report.writer import make_report, paper_results, summarise


def _paper_store(root: Path, drop: tuple[str, str] | None = None) -> dict:
    """A store whose per-seed worst/average cases have exactly the paper's means and stds
    (10 seeds at mean ± std), and dynamic episodes with Table 6's means and stds."""
    paper = paper_results()
    signs = np.tile([1.0, -1.0], 5)  # mean 0, std (ddof=0) 1
    skew = np.array([-1 / 3] * 9 + [3.0])  # also mean 0, std 1
    ev_rows, dyn_rows, runs = [], [], []
    for algo, tasks in paper["raw_worst_case"].items():
        for task, (w, sw) in tasks.items():
            if (algo, task) == drop:
                continue
            a, sa = paper["raw_average_case"][algo][task]
            # a seed's worst case cannot exceed its average case: pick a pattern that allows it
            z = next(z for z in (signs, skew, -skew) if np.all(w + sw * z <= a + sa * z))
            for seed, s in enumerate(z):
                worst, avg = w + sw * s, a + sa * s
                other = (3 * avg - worst) / 2  # points (worst, other, other): mean avg, min worst
                key = dict(algorithm=algo, task=task, uncertainty="3d", seed=seed, steps=5_000_000)
                for point, ret in enumerate((worst, other, other)):
                    ev_rows.append({**key, "point": point, "episode": 0, "return": ret})
                runs.append({**key, "worst_case": worst, "average_case": avg})
                if algo in paper["dynamic"]:
                    m, sd = paper["dynamic"][algo][task]
                    dyn_rows.append({**key, "episode": 0, "return": m + sd * signs[seed]})
    results = root / "results"
    results.mkdir(parents=True)
    pd.DataFrame(ev_rows).to_csv(results / "evaluations.csv", index=False)
    pd.DataFrame(dyn_rows).to_csv(results / "dynamic.csv", index=False)
    pd.DataFrame(runs).to_csv(results / "runs.csv", index=False)
    pd.DataFrame(columns=["algorithm", "task", "seed", "step", "steps"]).to_csv(
        results / "curves.csv", index=False
    )
    return paper


def test_report_reproduces_the_papers_normalised_tables(tmp_path, capsys):
    paper = _paper_store(tmp_path)
    assert main(["report", str(tmp_path), "--no-plots"]) == 0
    summary = json.loads((tmp_path / "report" / "summary.json").read_text())
    res = summary["results"]
    for algo, tasks in paper["raw_worst_case"].items():
        for task, (mean, std) in tasks.items():
            cell = res[task][algo]["worst_case"]
            assert cell["mean"] == pytest.approx(mean) and cell["std"] == pytest.approx(std)
            assert cell["n_seeds"] == 10 and cell["ci95"][0] < mean < cell["ci95"][1]
    for metric in ("worst_case", "average_case"):
        for algo, tasks in paper[f"normalised_{metric}"].items():
            for task, printed in tasks.items():
                ours = res[task][algo]["normalised"][metric]["mean"]
                if (metric, algo, task) == ("average_case", "nrmdp", "ant"):
                    # the paper's known typo: it prints 0.44, its raw numbers give 0.54
                    assert printed == 0.44 and round(ours, 2) == 0.54
                else:  # the paper rounds (or truncates) to 2 decimals
                    assert abs(ours - printed) <= 0.01, (metric, algo, task, ours, printed)
    # Table 6 from its episodes, and the Average column of Table 4 (mean of the task means)
    for algo, tasks in paper["dynamic"].items():
        for task, (mean, std) in tasks.items():
            assert res[task][algo]["dynamic"]["mean"] == pytest.approx(mean)
            assert res[task][algo]["dynamic"]["std"] == pytest.approx(std)
    agg = summary["aggregate"]["dr"]["normalised_worst_case"]
    assert round(agg["mean_over_tasks"], 2) == 0.52 and round(agg["std_over_tasks"], 2) == 1.16
    md = (tmp_path / "report" / "report.md").read_text()
    assert "(paper 0.44)" in md and "Known erratum" in md
    assert main(["report", str(tmp_path), "--no-plots", "--cells", "pm"]) == 0  # the paper's
    tex = (tmp_path / "report" / "tables" / "normalised_worst_case.tex").read_text()
    assert "DR & $0.06 \\pm 0.16$" in tex and "Average" in tex
    dyn = (tmp_path / "report" / "tables" / "dynamic.tex").read_text()  # the paper's units
    assert "HumanoidStandup ($10^4$)" in dyn and "RARL & $2.90 \\pm 0.70$" in dyn
    assert not summary["missing"]


def test_partial_report_names_the_missing_cells(tmp_path):
    _paper_store(tmp_path, drop=("rarl", "hopper"))
    make_report(tmp_path, plots=False)
    summary = json.loads((tmp_path / "report" / "summary.json").read_text())
    assert summary["missing"] == ["rarl/hopper: no finished run"]
    assert summary["results"]["hopper"]["rarl"]["worst_case"]["mean"] is None
    assert "## Missing cells" in (tmp_path / "report" / "report.md").read_text()


@pytest.mark.e2e
def test_bootstrap_cis_are_reproducible_for_a_seed(tmp_path):
    _paper_store(tmp_path)
    first, second = summarise(tmp_path), summarise(tmp_path)
    assert first["aggregate"] == second["aggregate"] and first["results"] == second["results"]
    x = np.array([3.0, 1.0, 4.0, 1.0, 5.0, 9.0, 2.0, 6.0])
    a = stats.bootstrap_ci([x], np.mean, np.random.default_rng(7))
    b = stats.bootstrap_ci([x], np.mean, np.random.default_rng(7))
    c = stats.bootstrap_ci([x], np.mean, np.random.default_rng(8))
    assert a == b and a != c and a[0] < x.mean() < a[1]
    assert stats.iqm([1, 2, 3, 4, 100, -100, 5, 6]) == pytest.approx(3.5)
    assert stats.improvement_probability(np.array([2.0, 3.0]), np.array([1.0, 3.0])) == 0.625
    poi = summarise(tmp_path)["aggregate"]["m2td3"]["poi_over_td3_worst_case"]
    assert 0.5 < poi["value"] <= 1 and poi["ci95"][0] <= poi["value"] <= poi["ci95"][1]
