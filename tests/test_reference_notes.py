"""The shipped references say, beside their budget and seeds, what a reader comparing them with
the paper must know: the physics, the library versions against the original code's pins and
M2TD3's share of learning steps, each read here from the shipped runs."""

from __future__ import annotations

from pathlib import Path

import pytest

from rrls.report.reference import load_reference
from rrls.rundir import read_run_json

ROOT = Path(__file__).resolve().parent.parent


@pytest.mark.parametrize("task", ["halfcheetah", "hopper-200k"])
def test_reference_notes_state_physics_versions_and_m2td3_share(task: str) -> None:
    ref = load_reference(ROOT / "rrls" / "report" / f"{task.replace('-', '_')}_reference.json")
    assert "reduced budget" in ref.label
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


@pytest.mark.parametrize("task", ["halfcheetah", "hopper-200k"])
def test_the_physics_sections_count_is_the_files(task: str) -> None:
    """The page's "N of M runs" (in progress until N = M) and the runs' cost are read from
    paper_physics.csv and runs/."""
    import csv
    import re

    folder = ROOT / "docs" / "results" / task
    with open(folder / "paper_physics.csv", newline="") as f:
        seconds = [float(row["seconds"]) for row in csv.DictReader(f)]
    measured = len(seconds)
    runs = len(list(folder.glob("runs/*/result.json")))
    page = (folder / "README.md").read_text()
    heading = re.search(r"paper's physics \((in progress: )?(\d+) of (\d+) runs\)", page)
    assert heading and (int(heading[2]), int(heading[3])) == (measured, runs)
    assert bool(heading[1]) == (measured < runs)  # "in progress" until every run is measured
    assert f"{measured} of the {runs} runs" in page
    cost = f"{min(seconds) / 60:.1f} to {max(seconds) / 60:.0f} minutes each, wall clock"
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


def test_the_hopper_budget_probes_table_is_its_file() -> None:
    """Each figure of the TD3 budget probe's table on the Hopper page is the file's, rounded."""
    import csv
    import re

    folder = ROOT / "docs" / "results" / "hopper-200k"
    with open(folder / "td3_budget_probe.csv", newline="") as f:
        rows = {
            (int(r["seed"]), int(r["step"])): float(r["nominal_return"]) for r in csv.DictReader(f)
        }
    page = (folder / "README.md").read_text()
    section = page.split("TD3 measured first", 1)[1].split("## Per run", 1)[0]
    tables = [t for t in re.split(r"\n\n", section) if t.startswith("| seed |")]
    assert len(tables) == 2  # to 300 k, then on towards 1 M
    shown = set()
    for table in tables:
        lines = table.strip().splitlines()
        steps = [
            int(c.strip().removesuffix(" k")) * 1000 for c in lines[0].strip("|").split("|")[1:]
        ]
        body = [line for line in lines[2:] if re.match(r"\| \d+ \|", line)]
        assert len(body) == len({seed for seed, _ in rows})
        for line in body:
            cells = [c.strip() for c in line.strip("|").split("|")]
            seed = int(cells[0])
            for step, cell in zip(steps, cells[1:], strict=True):
                expected = rows.get((seed, step))
                assert cell == ("" if expected is None else f"{expected:.0f}"), (seed, step)
                shown.add((seed, step))
    assert {key for key in rows if key[1] >= 50_000} <= shown  # every measured point shown
    finals = [rows[(seed, 300_000)] for seed in (0, 1)]
    reading = " ".join(page.split())
    assert f"TD3 is at {finals[0]:.0f} (seed 0) and {finals[1]:.0f} (seed 1), far from 2 500" in (
        reading
    )
    assert max(finals) < 2_500  # the rule the reading says is not met
    if (0, 450_000) in rows:  # seed 0's swing, read from the file
        passed, fell = rows[(0, 400_000)], rows[(0, 450_000)]
        assert passed >= 2_500 > fell
        assert f"400 k ({passed:.0f}) and fell to {fell:.0f} at the next evaluation" in reading
