"""The Warp twin's pages state only what their shipped data show: the check table is rendered
from ``check.csv``, every speed table is the logs' own, and each number quoted in prose is read
from the logs or ``divergence.csv`` here (no warp needed)."""

from __future__ import annotations

import csv
import importlib.util
import json
import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
RECORD = DOCS / "results" / "gpu" / "h100-2026-11-27"


def _twin_check():
    spec = importlib.util.spec_from_file_location("twin_check", ROOT / "benchmarks/twin_check.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules["twin_check"] = module
    spec.loader.exec_module(module)
    return module


def table_lines(path: Path) -> list[str]:
    return [line for line in path.read_text().splitlines() if line.startswith("|")]


def row(log: str, *cells: str) -> list[str]:
    """The cells of the log's table row that starts with ``cells``."""
    for line in table_lines(RECORD / log):
        parts = [c.strip() for c in line.strip("|").split("|")]
        if parts[: len(cells)] == list(cells):
            return parts
    raise AssertionError(f"no row {cells} in {log}")


def test_the_check_tables_are_rendered_from_the_shipped_csvs():
    markdown = _twin_check().markdown
    twin, record = (DOCS / "twin.md").read_text(), (RECORD.parent / f"{RECORD.name}.md").read_text()
    assert markdown(DOCS / "results" / "twin" / "check.csv") in twin
    assert markdown(RECORD / "twin_check.csv") in record


def test_the_speed_tables_are_the_logs_own():
    twin, record = (DOCS / "twin.md").read_text(), (RECORD.parent / f"{RECORD.name}.md").read_text()
    for log in ("warp_speed.log", "twin_speed.log", "twin_train.log"):
        for line in table_lines(RECORD / log):
            assert line in record, (log, line)
    for log in ("twin_speed.log", "twin_train.log"):
        for line in table_lines(RECORD / log):
            assert line in twin, (log, line)


def test_prose_numbers_are_read_from_the_data():
    twin = (DOCS / "twin.md").read_text()
    performance = (DOCS / "performance.md").read_text()
    protocol = (DOCS / "protocol.md").read_text()
    hopper_4096 = row("twin_speed.log", "hopper", "4096")[2]
    rate = float(hopper_4096.replace(",", ""))
    assert f"runs {hopper_4096} env steps/s, {rate / 200_000:.1f}× the 200 000" in twin
    assert f"Hopper: {hopper_4096} env steps/s at 4 096 worlds" in " ".join(performance.split())
    k = {n: row("twin_train.log", "td3", "hopper", n)[3] for n in ("1", "32", "128")}
    text = " ".join(protocol.split())
    assert f"train at {k['128']} env steps/s together (K = 1: {k['1']}, K = 32: {k['32']})" in text
    hours = 250 * 5_000_000 / float(k["128"].replace(",", "")) / 3600
    assert f"≈ {hours:.0f} h** of training" in text

    with (DOCS / "results" / "twin" / "divergence.csv").open() as f:
        rows = {int(r["step"]): r for r in csv.DictReader(f)}

    def at(task: str, step: int) -> float:
        return float(rows[step][task])

    prose = " ".join(twin.split())
    cheetah10 = max(at("halfcheetah", t) for t in range(1, 11))
    assert f"HalfCheetah stays within {cheetah10:.1e} for 10 steps" in prose
    assert f"({at('halfcheetah', 100):.2f} at 100 steps, {at('halfcheetah', 1000):.1f} at" in prose
    assert f"Ant is the contact difference above ({at('ant', 100):.1f} at 100 steps)" in prose
    for task in ("hopper", "walker", "invertedpendulum"):  # "stop early": within 50 steps
        assert all(r[task] == "nan" for s, r in rows.items() if s > 50), task
    assert re.search(r"end Hopper's, Walker2d's and\s+InvertedPendulum's episodes within 50", twin)


def test_the_step_floor_is_read_from_the_speed_log():
    twin = " ".join((DOCS / "twin.md").read_text().split())
    rate = row("twin_speed.log", "hopper", "32")[2]
    floor_ms = 32 / float(rate.replace(",", "")) * 1000
    assert f"at 32 worlds it takes {floor_ms:.1f} ms ({rate} env steps/s" in twin
    k1 = row("twin_train.log", "td3", "hopper", "1")[3]
    assert f"({k1} env steps/s against 784 on the same kind of machine)" in twin
    first = (RECORD.parent / "h100-2026-11-25.md").read_text()
    assert "| cuda | td3 | 1 | 784 |" in first  # the CPU-physics figure quoted


def test_the_sim_to_sim_tables_and_numbers_are_the_csvs():
    spec = importlib.util.spec_from_file_location("twin_train", ROOT / "benchmarks/twin_train.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules["twin_train"] = module
    spec.loader.exec_module(module)
    folder = DOCS / "results" / "twin" / "sim_to_sim"
    twin = (DOCS / "twin.md").read_text()
    ratios = {}
    for task in ("invertedpendulum", "halfcheetah"):
        assert module.markdown_from_csv(folder / f"{task}.csv") in twin, task
        with (folder / f"{task}.csv").open() as f:
            rows = list(csv.DictReader(f))
        ratios[task] = [float(r["twin_return"]) / float(r["cpu_return"]) for r in rows]
    prose = " ".join(twin.split())
    ip, hc = (
        sum(abs(r - 1) <= 0.01 for r in ratios[t]) for t in ("invertedpendulum", "halfcheetah")
    )
    assert f"within 1 % at {ip} of 8 InvertedPendulum points and {hc} of 8 HalfCheetah" in prose
    assert f"up to {max(ratios['halfcheetah']):.2f}× on one point" in prose
    with (folder / "td3-invertedpendulum-warp" / "scalars.csv").open() as f:
        last = [r for r in csv.DictReader(f) if r["metric"] == "eval/nominal_return"][-1]
    assert f"nominal return {float(last['value']):.1f} of 1 000" in prose
    run = json.loads((folder / "td3-invertedpendulum-warp" / "run.json").read_text())
    assert run["simulator"] == "warp"
    assert (
        f"--steps {run['steps']} " in prose
        and f"at {run['steps']:,} steps".replace(",", " ") in prose
    )
    assert len(ratios["invertedpendulum"]) == len(ratios["halfcheetah"]) == 8  # "8 points"


def test_the_fresh_dr_cost_table_is_the_median_of_its_log():
    """docs/twin.md's pool / ``pool=0`` table: per task, the median over the log's three runs of
    each rate and of each run's ratio."""
    import statistics

    runs: dict[str, list[list[float]]] = {}
    for line in table_lines(DOCS / "results" / "twin" / "pool_cpu.log"):
        cells = [c.strip() for c in line.strip("|").split("|")]
        if cells[0] in ("hopper", "halfcheetah"):
            runs.setdefault(cells[0], []).append(
                [float(cells[i].replace(",", "")) for i in (2, 4, 5)]
            )
    twin = (DOCS / "twin.md").read_text()
    names = {"hopper": "Hopper", "halfcheetah": "HalfCheetah"}
    for task, rows in runs.items():
        assert len(rows) == 3
        pool, fresh, ratio = (statistics.median(column) for column in zip(*rows))
        assert f"| {names[task]} | {pool:.0f} | {fresh:.0f} | {ratio:.2f} |" in twin, task


def test_the_solver_comparison_numbers_are_its_files():
    """The twin page's PGS-against-CG/Newton sentence: every number read from ``solver.csv``."""
    rows = list(csv.DictReader((DOCS / "results" / "twin" / "solver.csv").open()))
    gap = {t: sorted(float(r[f"qpos_gap_{t}"]) for r in rows) for t in (1, 10, 100)}
    rel = max(abs(float(r["return_solver"]) / float(r["return_pgs"]) - 1) for r in rows)
    text = " ".join((DOCS / "twin.md").read_text().split())
    assert f"is {gap[1][-1]:.1e} after one env step and {gap[10][-1]:.1e} after 10" in text
    below = sum(g < 1e-5 for g in gap[100])
    assert f"after 100 steps {below} of the {len(rows)} runs stay below 1e-05" in text
    assert f"one drifts apart ({gap[100][-1]:.3f}" in text and below == len(rows) - 1
    assert f"differ by at most {rel * 100:.2f} %" in text
    assert gap[10][-1] < 1e-5  # below the twin's own tolerance against CPU MuJoCo (1e-5)
