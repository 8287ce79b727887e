"""The shipped references say, beside their budget and seeds, what a reader comparing them with
the paper must know: the physics, the library versions against the original code's pins and
M2TD3's share of learning steps, each read here from the shipped runs."""

from __future__ import annotations

from pathlib import Path

import pytest

from rrls.report.reference import load_reference
from rrls.rundir import read_run_json

ROOT = Path(__file__).resolve().parent.parent


@pytest.mark.parametrize("task", ["halfcheetah", "hopper-200k", "hopper"])
def test_reference_notes_state_physics_versions_and_m2td3_share(task: str) -> None:
    ref = load_reference(ROOT / "rrls" / "report" / f"{task.replace('-', '_')}_reference.json")
    assert "reduced budget" in ref.label
    assert "\\" not in ref.notes  # plain text: no escape a shell or a format left behind
    runs = [read_run_json(p) for p in (ROOT / "docs/results" / task).glob("runs/*")]
    mujoco = {r["versions"]["mujoco"] for r in runs}
    gymnasium = {r["versions"]["gymnasium"] for r in runs}
    assert len(mujoco) == len(gymnasium) == 1
    assert f"MuJoCo {mujoco.pop()} and Gymnasium {gymnasium.pop()}" in ref.notes
    assert "pins, MuJoCo 2.3.3 and Gymnasium 1.0.0a1" in ref.notes
    assert "derived constants recomputed" in ref.notes and "not the paper's" in ref.notes
    warmup = {r["config"]["hyper"]["learning_starts"] for r in runs if r["algorithm"] == "m2td3"}
    assert len(warmup) == 1
    learn = ref.steps - warmup.pop()
    assert (
        f"M2TD3's learning steps: {learn:,} of {ref.steps:,} ({learn / ref.steps:.0%}" in ref.notes
    )


@pytest.mark.parametrize("task", ["halfcheetah", "hopper-200k", "hopper"])
def test_the_physics_sections_count_is_the_files(task: str) -> None:
    """The page's "N of M runs" (in progress until N = M) and the runs' cost are read from
    paper_physics.csv and runs/."""
    import csv
    import re

    folder = ROOT / "docs" / "results" / task
    with open(folder / "paper_physics.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    seconds = [float(row["seconds"]) for row in rows if row["seconds"]]  # empty: not timed whole
    measured = len(rows)
    runs = len(list(folder.glob("runs/*/result.json")))
    page = (folder / "README.md").read_text()
    # a grid in progress counts the runs shipped so far
    heading = re.search(
        r"paper's physics \((in progress: )?(\d+) of (\d+) runs( shipped so far)?\)", page
    )
    assert heading and (int(heading[2]), int(heading[3])) == (measured, runs)
    assert bool(heading[1]) == (measured < runs)  # "in progress" until every run is measured
    assert f"{measured} of the {runs} runs" in " ".join(page.split())
    cost = f"{min(seconds) / 60:.1f} to {max(seconds) / 60:.0f} minutes each, wall clock"
    if len(seconds) == 1:
        cost = f"{seconds[0] / 60:.0f} minutes each, wall clock"
    if len(seconds) < measured:
        cost += f" at `nice 19`, for the {len(seconds)} runs timed whole"
        untimed = measured - len(seconds)
        words = {1: "one", 2: "two", 3: "three", 4: "four", 5: "five"}
        assert f"the {words.get(untimed, untimed)} resumed" in " ".join(page.split())
    assert cost in " ".join(page.split()), cost


@pytest.mark.parametrize("task", ["halfcheetah", "hopper-200k"])
def test_the_physics_sections_summary_is_the_files(task: str) -> None:
    """Where a page says every mean worst case rises on the paper's physics, by how much is
    read from paper_physics.csv (per algorithm: the mean over its runs of paper minus v5)."""
    import csv

    folder = ROOT / "docs" / "results" / task
    page = " ".join((folder / "README.md").read_text().split())
    if "Every mean worst case rises" not in page:
        pytest.skip(f"{task}'s page states no change of the worst case yet")
    change: dict[str, list[float]] = {}
    with open(folder / "paper_physics.csv", newline="") as f:
        for row in csv.DictReader(f):
            delta = float(row["worst_case_paper"]) - float(row["worst_case_v5"])
            change.setdefault(row["algorithm"], []).append(delta)
    means = [sum(v) / len(v) for v in change.values()]
    assert min(means) > 0
    assert f"(by {min(means):.0f} to {max(means):.0f})" in page


@pytest.mark.parametrize("task", ["halfcheetah", "hopper-200k", "hopper"])
def test_a_page_that_says_no_physics_change_is_resolved_has_none(task: str) -> None:
    """The words "every paired interval holds 0" are read from paper_physics.csv: per algorithm and
    statistic, the paired 95 % interval of paper minus v5 (SciPy's ``ttest_rel``)."""
    import sys

    from scipy.stats import ttest_rel

    sys.path.insert(0, str(ROOT / "benchmarks"))
    import page_checks

    folder = ROOT / "docs" / "results" / task
    page = " ".join((folder / "README.md").read_text().split())
    holds = []
    for by in page_checks.read_physics(folder / "paper_physics.csv").values():
        for metric in ("worst_case", "average_case"):
            paper, v5 = by[f"{metric}_paper"], by[f"{metric}_v5"]
            if len(v5) > 1:
                ci = ttest_rel(paper, v5).confidence_interval()
                holds.append(ci.low <= 0 <= ci.high)
    assert ("every paired interval holds 0" in page) == all(holds), holds


def test_what_the_paper_physics_moves_on_halfcheetah_is_the_files() -> None:
    """The HalfCheetah page's reading of its physics block, read from paper_physics.csv: the
    worst-case orderings the corrected test resolves on the paper's physics and not on v5 (each
    the paper's way), the largest mean rise and the runs moving both ways, and which paired
    intervals exclude 0."""
    import sys

    from scipy.stats import ttest_rel

    from rrls.algorithms import display_name, sort_algos
    from rrls.report.writer import paper_results

    sys.path.insert(0, str(ROOT / "benchmarks"))
    import page_checks

    folder = ROOT / "docs" / "results" / "halfcheetah"
    page = " ".join((folder / "README.md").read_text().split())
    data = page_checks.read_physics(folder / "paper_physics.csv")
    assert all(len(by["worst_case_v5"]) == 5 for by in data.values())
    algos = sort_algos(data)  # the block's order
    worst = {k: {a: data[a][f"worst_case_{k}"] for a in algos} for k in ("v5", "paper")}
    # the same order by mean; none resolved on v5, five on the paper's physics, the paper's way
    assert page_checks.ranked(worst["v5"]) == page_checks.ranked(worst["paper"])
    assert page_checks.resolved(worst["v5"]) == []
    gained = page_checks.resolved(worst["paper"])
    paper = paper_results()["raw_worst_case"]
    assert all(paper[a]["halfcheetah"][0] > paper[b]["halfcheetah"][0] for a, b in gained)
    names = [f"{display_name(a)} > {display_name(b)}" for a, b in gained]
    listed = ", ".join(names[:-1]) + " and " + names[-1]
    assert f"it resolves {len(gained)}, each the paper's way: {listed}" in page.replace("five", "5")
    verdict = f"the corrected test reproduces {len(gained)} of the paper's worst-case orderings"
    assert f"{verdict}: {listed}" in page.replace("five", "5")  # the verdict's section too
    # DR rises most; its runs and M2TD3's move both ways; every worst-case interval holds 0
    change = {
        a: {
            m: [p - v for v, p in zip(by[f"{m}_v5"], by[f"{m}_paper"])]
            for m in ("worst_case", "average_case")
        }
        for a, by in data.items()
    }
    mean = {a: {m: sum(d) / len(d) for m, d in c.items()} for a, c in change.items()}
    assert max(mean, key=lambda a: mean[a]["worst_case"]) == "dr"
    assert f"DR's worst case rises most (+{mean['dr']['worst_case']:.1f} on average)" in page
    for a in ("dr", "m2td3"):
        assert min(change[a]["worst_case"]) < 0 < max(change[a]["worst_case"])

    def excludes_zero(a: str, m: str) -> bool:
        ci = ttest_rel(data[a][f"{m}_paper"], data[a][f"{m}_v5"]).confidence_interval()
        return not ci.low <= 0 <= ci.high

    assert not any(excludes_zero(a, "worst_case") for a in data)
    assert "every worst-case paired interval holds 0" in page
    assert all(abs(mean[a]["average_case"]) < 30 for a in data)
    assert [a for a in data if excludes_zero(a, "average_case")] == ["td3"]
    assert f"TD3's rise (+{mean['td3']['average_case']:.1f}) is the one paired interval" in page


def test_the_hopper_budget_is_the_probes_rule_and_its_file() -> None:
    """The Hopper page's budget, its reading and its costs are read from the probe's file, the
    shipped TD3 runs and the preset: 700 k is the first 50 k mark (>= 300 k) where TD3 is at
    least 2 500 on both probed seeds; the shipped seed 0 is the probe's run, and seed 1, trained
    again on another CPU kind, gave the probe's evaluations."""
    import csv
    import json

    from rrls.benchmark.cpu_estimate import estimate
    from rrls.benchmark.grid import make_spec

    folder = ROOT / "docs" / "results" / "hopper"
    with open(folder / "td3_budget_probe.csv", newline="") as f:
        rows = {
            (int(r["seed"]), int(r["step"])): float(r["nominal_return"]) for r in csv.DictReader(f)
        }
    spec = make_spec("hopper")
    marks = sorted({step for _, step in rows if step >= 300_000 and step % 50_000 == 0})
    both = [m for m in marks if all(rows.get((s, m), 0.0) >= 2_500 for s in (0, 1))]
    assert both and both[0] == spec.steps == 700_000
    page = " ".join((folder / "README.md").read_text().split())
    first = {
        s: min(step for (seed, step), v in rows.items() if seed == s and v >= 2_500) for s in (0, 1)
    }
    assert f"Seed 0 first reached 2 500 at {first[0] // 1000} k" in page
    assert f"seed 1 first reached it at {first[1] // 1000} k" in page
    assert any(rows[(0, m)] < 2_500 for m in marks if first[0] < m < spec.steps)  # "fell back"
    after = rows[(0, 750_000)]
    assert f"was at {after:,.0f} at 750 k".replace(",", " ") in page
    # the shipped seed 0 is the probe's run: its evaluations are the file's; seed 1, trained
    # again from step 0 on another CPU kind, evaluated every 50 k: the file's at each of them
    every_50k = set(range(50_000, spec.steps + 1, 50_000))
    for seed in (0, 1):
        path = folder / "runs" / f"td3-hopper-3d-seed{seed}" / "scalars.csv"
        if not path.exists():
            continue
        with open(path, newline="") as f:
            evals = {
                int(r["step"]): float(r["value"])
                for r in csv.DictReader(f)
                if r["metric"] == "eval/nominal_return"
            }
        probe = {step: v for (s, step), v in rows.items() if s == seed and step <= spec.steps}
        assert set(evals) == (set(probe) if seed == 0 else every_50k)
        assert {k: round(v, 4) for k, v in evals.items()} == {k: probe[k] for k in evals}
    seed1 = folder / "runs" / "td3-hopper-3d-seed1" / "run.json"
    if seed1.exists():  # "the same 14 evaluations", trained on X86_V4 where the probe had X86_V3
        assert f"at each of the {len(every_50k)} evaluations, every 50 000 steps" in page
        run0 = json.loads((folder / "runs" / "td3-hopper-3d-seed0" / "run.json").read_text())
        assert run0["provenance"]["machine"]["simd"] == "X86_V3"
        trained = json.loads(seed1.read_text())["provenance"]["executions"]
        assert trained[0]["first_step"] == 0
        assert {e["machine"]["simd"] for e in trained} == {"X86_V4"}
    executions = folder / "runs" / "td3-hopper-3d-seed0" / "executions.csv"
    if executions.exists():  # the probe trained past the budget before the checkpoint was taken
        with open(executions, newline="") as f:
            last = max(int(r["last_step"]) for r in csv.DictReader(f))
        assert last > spec.steps and f"(seed 0 to {last // 1000} k" in page
    learn = spec.steps - spec.warmup("m2td3")
    assert f"M2TD3 learns for {learn:,} of the {spec.steps:,} steps".replace(",", " ") in page
    assert f"({learn / spec.steps:.0%}".replace("%", " %") in page
    cost = estimate(spec, 2)
    assert f"estimates {cost['cpu_s'] / 3600:.1f} CPU-hours" in page
    assert f"({cost['train_s'] / 3600:.1f} of them training)" in page


@pytest.mark.parametrize("task", ["halfcheetah", "hopper"])
def test_the_mujoco_versions_a_page_names_in_prose_are_its_runs_and_the_originals(task: str):
    """The prose's "MuJoCo 2.3.3 (the original's pin) and 4.0.0" is the original code's pin
    and the version every shipped run recorded."""
    import sys

    sys.path.insert(0, str(ROOT / "benchmarks"))
    import page_checks

    folder = ROOT / "docs" / "results" / task
    page = " ".join((folder / "README.md").read_text().split())
    used = {read_run_json(p.parent)["versions"]["mujoco"] for p in folder.glob("runs/*/run.json")}
    assert len(used) == 1
    original = page_checks.ORIGINAL["mujoco"]
    assert f"MuJoCo {original} (the original's pin) and {used.pop()}" in page
