"""``rrls report DIR DIR --out OUT``: the paper's cross-task Tables 4-5 over references trained a
task at a time (the shipped HalfCheetah and Hopper references), each task's cells those of its
own report."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pandas as pd
import pytest

from rrls.benchmark.benchfile import read_spec, stored_fingerprints
from rrls.benchmark.store import build_store
from rrls.cli.app import main
from rrls.report.crosstask import joined
from rrls.report.writer import paper_results

pytestmark = pytest.mark.e2e  # rrls report over two shipped references: a long run

RESULTS = Path(__file__).resolve().parent.parent / "docs" / "results"
TASKS = ("halfcheetah", "hopper")
#: each task's shipped reference folder
FOLDERS = {"halfcheetah": "halfcheetah", "hopper": "hopper"}


def _copy(name: str, dest: Path) -> Path:
    """A shipped reference's runs and protocol, its store built (the shipped folder untouched)."""
    src = RESULTS / name
    dest.mkdir(parents=True)
    for f in ("benchmark.json", "benchmark.json.sha256"):
        shutil.copy2(src / f, dest / f)
    shutil.copytree(src / "runs", dest / "runs")
    build_store(dest, stored_fingerprints(dest))
    return dest


@pytest.fixture(scope="module")
def joined_report(tmp_path_factory: pytest.TempPathFactory) -> dict:
    root = tmp_path_factory.mktemp("cross")
    dirs = [_copy(FOLDERS[t], root / t) for t in TASKS]
    assert main(["report", *map(str, dirs), "--out", str(root / "out"), "--no-plots"]) == 0
    report = root / "out" / "report"
    return {"dirs": dirs, "root": root, "report": report}


def test_each_task_reads_as_in_its_own_report(joined_report: dict) -> None:
    summary = json.loads((joined_report["report"] / "summary.json").read_text())
    assert summary["tasks"] == list(TASKS)
    for task in TASKS:
        own = json.loads((RESULTS / FOLDERS[task] / "summary.json").read_text())
        assert summary["results"][task] == own["results"][task]
        assert summary["pairwise"][task] == own["pairwise"][task]
        assert summary["normalisation"][task] == own["normalisation"][task]
        # a task's planned seeds are its own: missing runs are those its own report lists
        assert [m for m in summary["missing"] if m.split(":")[0].endswith(f"/{task}")] == (
            own["missing"]
        )


def test_average_column_is_the_mean_over_tasks(joined_report: dict) -> None:
    """The paper's Table 4's Average: the mean over tasks of each algorithm's normalised mean."""
    table = pd.read_csv(joined_report["report"] / "tables" / "normalised_worst_case.csv")
    assert set(table["task"]) == set(TASKS)
    summary = json.loads((joined_report["report"] / "summary.json").read_text())
    for algo, rows in table.groupby("algorithm"):
        expected = rows.set_index("task")["mean"].mean()
        assert summary["aggregate"][algo]["normalised_worst_case"]["mean_over_tasks"] == (
            pytest.approx(expected, abs=1e-12)
        )
    md = (joined_report["report"] / "report.md").read_text()
    assert "| algorithm | HalfCheetah | Hopper | Average | IQM [95% CI] |" in md


def test_each_tasks_budget_is_stated(joined_report: dict) -> None:
    """Each task's own budget, seeds and episodes, read from its benchmark.json."""
    md = (joined_report["report"] / "report.md").read_text()
    tex = (joined_report["report"] / "tables" / "normalised_worst_case.tex").read_text()
    budgets = []
    for task, name in zip(TASKS, ("HalfCheetah", "Hopper"), strict=True):
        spec = read_spec(RESULTS / FOLDERS[task])
        steps, seeds, episodes = spec.steps, len(spec.seeds), spec.protocol.episodes
        budgets.append({"steps": steps, "episodes": episodes})
        assert f"| {name} | " in md and f"| {steps:,} | {seeds} | {episodes} |" in md
        assert (
            f"{name} {steps:,} steps per run, {seeds} seeds, {episodes} episodes per point" in tex
        )
    differ = [key for key in ("steps", "episodes") if budgets[0][key] != budgets[1][key]]
    assert differ and f"The tasks differ in {', '.join(differ)}:" in md
    assert "Training budget: " not in tex  # no single budget claimed for both


def test_a_task_from_two_benchmarks_is_refused(joined_report: dict, capsys) -> None:
    hc = joined_report["dirs"][0]
    code = main(["report", str(hc), str(hc), "--out", str(joined_report["root"] / "o2")])
    err = capsys.readouterr().err
    assert code == 2 and "task 'halfcheetah' is in both" in err and err.count("\n") == 1


def test_benchmarks_of_another_set_are_refused(joined_report: dict, tmp_path: Path) -> None:
    tables, spec = joined(joined_report["dirs"])
    assert spec["steps"] is None and spec["uncertainty"] == "3d"
    other = tmp_path / "other"
    shutil.copytree(joined_report["dirs"][1], other)
    data = json.loads((other / "benchmark.json").read_text())
    (data["protocol"] if "protocol" in data else data)["mesh"] = 5  # either spec layout
    from rrls import files

    files.write_checked_json(other / "benchmark.json", data)
    with pytest.raises(ValueError, match="differ in mesh"):
        joined([joined_report["dirs"][0], other])


@pytest.mark.parametrize(
    "extra, message",
    [
        ([], "two or more DIRs and --out OUT"),
        (["--reference", "quick"], "--reference applies to one benchmark"),
    ],
)
def test_joined_report_usage(joined_report: dict, capsys, extra: list, message: str) -> None:
    dirs = [str(d) for d in joined_report["dirs"]]
    argv = ["report", dirs[0], "--out", str(joined_report["root"] / "o3")]
    if extra:
        argv = ["report", *dirs, "--out", str(joined_report["root"] / "o3"), *extra]
    assert main(argv) == 2
    assert message in capsys.readouterr().err


def test_the_shipped_cross_task_report_is_the_commands(joined_report: dict) -> None:
    """docs/results/cross-task holds what the command writes over the shipped references."""
    made = json.loads((joined_report["report"] / "summary.json").read_text())
    shipped = json.loads((RESULTS / "cross-task" / "summary.json").read_text())
    for key in ("tasks", "algorithms", "results", "aggregate", "pairwise", "missing"):
        assert shipped[key] == made[key], key
    assert (
        shipped["benchmark"]["by_task"]["hopper"]["steps"]
        == read_spec(RESULTS / FOLDERS["hopper"]).steps
    )
    for name in ("normalised_worst_case", "normalised_average_case"):
        pd.testing.assert_frame_equal(
            pd.read_csv(RESULTS / "cross-task" / "tables" / f"{name}.csv"),
            pd.read_csv(joined_report["report"] / "tables" / f"{name}.csv"),
        )


def test_the_cross_task_page_says_which_scores_normalise() -> None:
    """The page's "§ on both tasks" and "the worst case normalises on both" are the report's."""
    shipped = json.loads((RESULTS / "cross-task" / "summary.json").read_text())
    page = " ".join((RESULTS / "cross-task" / "README.md").read_text().split())
    unstable = {(u["task"], u["metric"]) for u in shipped["unstable"]}
    tasks = set(shipped["tasks"])
    assert unstable == {(task, "average_case") for task in tasks} and len(tasks) == 2
    assert "The average case carries § on both tasks" in page
    assert "The worst case normalises on both." in page
    names = paper_results()["task_names"]
    for task, folder in FOLDERS.items():  # "(300 k steps, ...)": each reference's own budget
        steps = read_spec(RESULTS / folder).steps // 1000
        assert f"[{names[task]} reference](../{folder}/README.md) ({steps} k steps" in page
