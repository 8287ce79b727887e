"""rrls benchmark / rrls report end to end on the smoke preset: the local pool and Ray, resume
after a killed driver, submissions, the paper's physics, splits, committed runs on a fresh machine
and files that are refused. What a benchmark checks and plans before it trains is in
``test_benchmark_plan.py``; the paper's own tables through the report in
``test_report_paper_tables.py``."""

from __future__ import annotations

import importlib.util
import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pandas as pd
import pytest
from conftest import e2e_after_first

from rrls.benchmark.benchfile import reconcile
from rrls.benchmark.grid import Benchmark, SpecError, make_spec
from rrls.cli import main

needs_torch = pytest.mark.skipif(
    importlib.util.find_spec("torch") is None, reason="training needs torch (rrls[train])"
)
REPO = Path(__file__).resolve().parents[1]
SMOKE = ["benchmark", "--preset", "smoke", "--workers", "2"]


@pytest.fixture(scope="module")
def smoke(tmp_path_factory) -> Path:
    """One uninterrupted smoke benchmark (5 algorithms, InvertedPendulum 1d, 1 seed)."""
    out = tmp_path_factory.mktemp("smoke")
    assert main([*SMOKE, "--out", str(out)]) == 0
    return out


@pytest.mark.e2e
@needs_torch
def test_an_exported_reference_says_where_it_came_from(smoke, tmp_path):
    from rrls.report.exported import export_reference
    from rrls.report.reference import load_reference

    export_reference(smoke, tmp_path / "ref.json")
    prov = load_reference(tmp_path / "ref.json").provenance
    assert prov["preset"] == "smoke" and prov["physics"] == "v5" and prov["runs"] == 5
    assert prov["seeds"] == [0] and prov["steps"] == 300 and prov["hidden"] == [16, 16]
    assert all(prov["versions"][k] for k in ("rrls", "torch", "mujoco", "gymnasium", "numpy"))
    assert prov["devices"] == ["cpu"] and len(prov["machines"]) == 1
    assert {"cpu", "cores", "simd"} <= set(prov["machines"][0]) and "commits" in prov
    # the hyper-parameters each algorithm trained with, as its runs recorded them
    hyper = prov["hyperparameters"]
    assert set(hyper) == {"td3", "dr", "rarl", "nrmdp", "m2td3"}
    run = json.loads(next((smoke / "runs").glob("m2td3-*/run.json")).read_text())
    assert hyper["m2td3"] == run["config"]["hyper"] and hyper["td3"]["hidden"] == [16, 16]
    assert "hyperparameters" not in run  # the run described once: its settings' hyper
    assert load_reference(tmp_path / "ref.json").notes.endswith(f"from {smoke.name}")
    # each row names the seed of each value, in JSON and CSV alike; a row whose seeds and
    # values disagree is refused
    rows = load_reference(tmp_path / "ref.json").rows
    assert rows and all(r["seeds"] == [0] and len(r["values"]) == 1 for r in rows)
    load_reference(tmp_path / "ref.json").save(tmp_path / "ref.csv")
    assert load_reference(tmp_path / "ref.csv").rows == rows
    data = json.loads((tmp_path / "ref.json").read_text())
    data["rows"][0]["seeds"] = [0, 1]
    (tmp_path / "bad.json").write_text(json.dumps(data))
    with pytest.raises(ValueError, match=r"rows\[0\]: 2 seeds for 1 values"):
        load_reference(tmp_path / "bad.json")
    export_reference(smoke, tmp_path / "noted.json", notes="300 steps: a smoke test")
    assert load_reference(tmp_path / "noted.json").notes == "300 steps: a smoke test"
    assert "trained_otherwise" not in prov  # every run trained as the benchmark says
    # a run re-evaluated under the benchmark's protocol but trained otherwise: the reference
    # says so, per algorithm
    from rrls.benchmark import store

    copy = tmp_path / "bench"
    shutil.copytree(smoke, copy)
    run = next((copy / "runs").glob("m2td3-*"))
    store.write_result(run, {**store.read_result(run), "trained_otherwise": {"learning_starts": 9}})
    export_reference(copy, tmp_path / "otherwise.json")
    prov = load_reference(tmp_path / "otherwise.json").provenance
    assert prov["trained_otherwise"] == {"m2td3": {"learning_starts": 9}}


@pytest.mark.e2e
@needs_torch
def test_the_report_lists_every_run_with_its_final_nominal_return(smoke):
    table = pd.read_csv(smoke / "report" / "tables" / "per_run.csv")
    assert len(table) == 5 and set(table["algorithm"]) == {"td3", "dr", "rarl", "nrmdp", "m2td3"}
    assert (table["steps"] == 300).all() and table["final_nominal_return"].notna().all()
    curves = pd.read_parquet(smoke / "results" / "curves.parquet")
    td3 = curves[(curves["algorithm"] == "td3")].dropna(subset=["eval_nominal_return"])
    last = td3.sort_values("step")["eval_nominal_return"].iloc[-1]
    assert table.set_index("algorithm").loc["td3", "final_nominal_return"] == pytest.approx(last)
    md = (smoke / "report" / "report.md").read_text()
    assert md.index("## Per run") < md.index("## Dynamic evaluation")


@pytest.mark.e2e
@needs_torch
def test_smoke_benchmark_writes_store_and_report(smoke):
    runs = sorted(p.parent.name for p in smoke.glob("runs/*/result.json"))
    assert len(runs) == 5
    ev = pd.read_parquet(smoke / "results" / "evaluations.parquet")
    # one row per (run, mesh point, episode), each carrying the run's identity and versions
    assert len(ev) == 5 * 2 * 1
    for col in (
        "algorithm",
        "task",
        "uncertainty",
        "seed",
        "steps",
        "point",
        "episode",
        "return",
        "rrls_version",
        "gymnasium_version",
        "mujoco_version",
        "polemass",
    ):
        assert col in ev, col
    curves = pd.read_parquet(smoke / "results" / "curves.parquet")
    assert {"step", "episode_return", "eval_nominal_return"} <= set(curves.columns)
    assert not curves.duplicated(["algorithm", "seed", "step"]).any()  # one row per (run, step)
    dyn = pd.read_parquet(smoke / "results" / "dynamic.parquet")
    assert sorted(dyn["algorithm"].unique()) == ["nrmdp", "rarl"]  # the two-player runs only
    summary = json.loads((smoke / "report" / "summary.json").read_text())
    cell = summary["results"]["invertedpendulum"]["rarl"]
    assert set(cell["worst_case"]) == {"mean", "std", "iqm", "ci95", "n_seeds"}
    assert cell["worst_case"]["n_seeds"] == 1 and cell["dynamic"]["episodes"] == 1
    assert summary["results"]["invertedpendulum"]["td3"]["normalised"]["worst_case"]["mean"] == 0
    for name in ("raw_worst_case", "normalised_worst_case", "normalised_average_case", "dynamic"):
        tex = (smoke / "report" / "tables" / f"{name}.tex").read_text()
        assert "\\toprule" in tex and "\\bottomrule" in tex
        assert (smoke / "report" / "tables" / f"{name}.csv").exists()
    md = (smoke / "report" / "report.md").read_text()
    assert "Reduced budget" in md and "figures/curves_episode_return.png" in md
    assert (smoke / "report" / "figures" / "curves_episode_return.png").stat().st_size > 5_000


@pytest.mark.e2e
@needs_torch
def test_rerun_skips_finished_runs_and_gives_the_same_summary(smoke, capsys):
    before = (smoke / "report" / "summary.json").read_bytes()

    def runs() -> dict[str, tuple[int, bytes]]:  # every run file, its mtime and its bytes
        files = (p for p in sorted((smoke / "runs").rglob("*")) if p.is_file())
        return {
            str(p): (p.stat().st_mtime_ns, p.read_bytes()) for p in files if p.suffix != ".lock"
        }

    kept = runs()
    assert main([*SMOKE, "--out", str(smoke)]) == 0
    assert runs() == kept  # nothing trained, evaluated or rewritten again
    assert "(5 finished, 0 to run)" in capsys.readouterr().err
    assert (smoke / "report" / "summary.json").read_bytes() == before


@pytest.mark.e2e
@needs_torch
def test_other_protocol_is_refused_naming_the_difference(smoke, capsys):
    assert main([*SMOKE, "--out", str(smoke), "--steps", "400", "--mesh", "3"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "steps" in err and "mesh" in err


@pytest.mark.e2e
@needs_torch
def test_adding_seeds_extends_the_benchmark(smoke, tmp_path):
    stored = Benchmark.from_json(json.loads((smoke / "benchmark.json").read_text()))
    grown = reconcile(smoke, make_spec("smoke", algos="td3,dr", seeds=3))
    assert grown.seeds == (0, 1, 2) and grown.algos == stored.algos
    with pytest.raises(SpecError, match="episodes"):
        reconcile(smoke, make_spec("smoke", episodes=4))


def _children(pid: int) -> list[int]:
    out = []
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        if int(fields[1]) == pid:
            out.append(int(stat.parent.name))
    return out


def _alive(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state != "Z"


@pytest.mark.e2e
@needs_torch
@pytest.mark.skipif(not Path("/proc").exists(), reason="needs /proc to find the run processes")
def test_killed_driver_leaves_no_process_and_rerun_gives_identical_numbers(smoke, tmp_path, capsys):
    out = tmp_path / "killed"
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    algos = ["--algos", "td3,rarl,m2td3,dr"]  # a smaller grid than the fixture's: test time
    broken = out / "runs" / "dr-invertedpendulum-1d-seed0"
    broken.mkdir(parents=True)
    (broken / "checkpoint.pt").write_bytes(b"not a checkpoint")  # this run must fail alone
    driver = subprocess.Popen(
        [sys.executable, "-m", "rrls", *SMOKE, "--out", str(out), *algos],
        cwd=REPO,
        env=env,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    deadline = time.monotonic() + 60
    children: list[int] = []
    while time.monotonic() < deadline:  # kill it while runs are in flight, one already done
        children = _children(driver.pid) or children
        in_flight = [p for p in out.glob("runs/*/checkpoint.pt") if p.parent != broken]
        if list(out.glob("runs/*/result.json")) and in_flight:
            break
        time.sleep(0.05)
    children = _children(driver.pid) or children
    driver.send_signal(signal.SIGKILL)
    driver.wait()
    assert children
    deadline = time.monotonic() + 10
    while any(_alive(p) for p in children) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not any(_alive(p) for p in children), "run processes outlived the driver"
    assert len(list(out.glob("runs/*/result.json"))) < 3  # it was really interrupted
    capsys.readouterr()
    assert main([*SMOKE, "--out", str(out), *algos]) == 1  # dr failed, the others went on
    err = capsys.readouterr().err
    assert "FAILED dr-invertedpendulum-1d-seed0" in err and "1 run(s) failed" in err
    assert (broken / "error.txt").exists() and not (broken / "result.json").exists()
    resumed = json.loads((out / "report" / "summary.json").read_text())["results"]
    whole = json.loads((smoke / "report" / "summary.json").read_text())["results"]
    for algo in ("td3", "rarl", "m2td3"):  # every number, normalised scores and CIs included
        assert resumed["invertedpendulum"][algo] == whole["invertedpendulum"][algo]


@pytest.mark.e2e
@needs_torch
def test_submitting_a_runs_policy_reproduces_its_numbers_in_the_report(smoke, tmp_path, capsys):
    """`rrls submit` evaluates under the benchmark's protocol: TD3's own run directory,
    submitted under another name (with RARL's adversary), gives TD3's numbers exactly, and
    `rrls report` shows it in every table and the figures with no other step."""
    import shutil

    bench = tmp_path / "bench"
    shutil.copytree(smoke, bench, ignore=shutil.ignore_patterns(".lock"))
    runs = bench / "runs"
    argv = ["submit", str(bench), "--algo", "td3-again", "--task", "invertedpendulum"]
    argv += ["--seed", "0", str(runs / "td3-invertedpendulum-1d-seed0")]
    argv += ["--adversary", str(runs / "rarl-invertedpendulum-1d-seed0" / "adversary.npz")]
    assert main(argv) == 0
    assert main(["report", str(bench)]) == 0
    out = capsys.readouterr().out
    assert "td3-again" in out
    summary = json.loads((bench / "report" / "summary.json").read_text())
    cells = summary["results"]["invertedpendulum"]
    for metric in ("worst_case", "average_case"):
        assert cells["td3-again"][metric] == cells["td3"][metric]
        assert cells["td3-again"]["normalised"][metric] == cells["td3"]["normalised"][metric]
    assert cells["td3-again"]["dynamic"]["n_seeds"] == 1
    assert "td3-again" in summary["aggregate"]
    assert summary["aggregate"]["td3-again"]["poi_over_td3_worst_case"]["value"] == 0.5
    for name in ("raw_worst_case", "normalised_average_case", "dynamic"):
        table = pd.read_csv(bench / "report" / "tables" / f"{name}.csv")
        assert "td3-again" in set(table["algorithm"])
        assert "td3-again" in (bench / "report" / "tables" / f"{name}.tex").read_text()
    ev = pd.read_parquet(bench / "results" / "evaluations.parquet")
    assert "td3-again" in set(ev["algorithm"])  # the return-over-set figure's data
    assert (bench / "report" / "figures" / "returns_invertedpendulum.png").exists()
    # `rrls benchmark` over the directory again neither trains nor drops the submission
    assert main([*SMOKE, "--out", str(bench)]) == 0
    again = json.loads((bench / "report" / "summary.json").read_text())
    assert again["results"]["invertedpendulum"]["td3-again"] == cells["td3-again"]


@pytest.mark.e2e
@needs_torch
def test_ray_backend_runs_the_same_function(smoke, tmp_path):
    ray = pytest.importorskip("ray", reason="the Ray backend needs `pip install rrls[ray]`")
    # the workers import this checkout's rrls (as the driver does), with no network beyond here
    env = {"PYTHONPATH": os.pathsep.join([str(REPO), os.environ.get("PYTHONPATH", "")])}
    ray.init(
        num_cpus=2, include_dashboard=False, log_to_driver=False, runtime_env={"env_vars": env}
    )
    try:
        out = tmp_path / "ray"
        code = main([*SMOKE, "--out", str(out), "--backend", "ray", "--algos", "td3,rarl"])
    finally:
        ray.shutdown()
    assert code == 0
    local = json.loads((smoke / "report" / "summary.json").read_text())["results"]
    remote = json.loads((out / "report" / "summary.json").read_text())["results"]
    for algo in ("td3", "rarl"):  # same numbers as the local pool (no M2TD3: no normalised)
        for metric in ("worst_case", "average_case", "dynamic"):
            mine = remote["invertedpendulum"][algo].get(metric)
            assert mine == local["invertedpendulum"][algo].get(metric)


@pytest.mark.e2e
@needs_torch
def test_quickstart_is_the_quick_preset(tmp_path, capsys, monkeypatch):
    from rrls.benchmark import grid as spec_module

    quick = spec_module.PRESETS["quick"]
    assert quick["tasks"] == ("invertedpendulum",) and quick["uncertainty"] == "1d"
    assert len(quick["algos"]) == 5 and quick["learning_rate"] == 1e-3
    # the real pipeline on a smoke-sized "quick" preset (the real one takes ~20 minutes)
    small = {**spec_module.PRESETS["smoke"], "algos": ("td3", "m2td3")}
    monkeypatch.setitem(spec_module.PRESETS, "quick", small)
    assert main(["quickstart", "--out", str(tmp_path), "--steps", "200"]) == 0
    out = capsys.readouterr().out
    assert "worst case" in out and "\ninvertedpendulum   TD3 " in out
    assert "† fewer than 3 seeds" in out  # one seed: the mark is explained
    assert json.loads((tmp_path / "benchmark.json").read_text())["preset"] == "quick"
    assert (tmp_path / "quickstart.png").stat().st_size > 10_000
    assert (tmp_path / "report" / "report.md").exists()


@pytest.mark.e2e
@needs_torch
def test_a_paper_physics_benchmark_trains_evaluates_and_records_it(tmp_path, capsys):
    # (with RARL against TC-RMDP's rate-limited adversary: trained and evaluated in that game)
    out = tmp_path / "paper"
    args = [*SMOKE, "--algos", "rarl", "--workers", "1", "--out", str(out), "--rate-limit", "0.1"]
    args += ["--observe", "oracle"]
    assert main([*args, "--physics", "paper"]) == 0
    assert json.loads((out / "benchmark.json").read_text())["protocol"]["physics"] == "paper"
    (run,) = (out / "runs").iterdir()
    assert json.loads((run / "run.json").read_text())["config"]["physics"] == "paper"
    summary = json.loads((run / "eval" / "summary.json").read_text())
    assert summary["physics"] == "paper" and summary["endpoint"] is False
    result = json.loads((run / "result.json").read_text())
    assert result["physics"] == "paper" and result["dynamic_env"].endswith("[paper]")
    assert "rate_limit=0.1, rate_game=tc, observe=oracle" in result["dynamic_env"]
    hyper = json.loads((run / "run.json").read_text())["config"]["hyper"]
    assert (hyper["rate_limit"], hyper["rate_game"], hyper["observe"]) == (0.1, "tc", "oracle")
    assert "protagonist_view" in summary  # the static evaluation showed it [s, ψ01] too
    capsys.readouterr()
    assert main(args) == 2  # the same directory on rrls's physics: another protocol
    assert "physics: 'paper' there, 'v5' now" in capsys.readouterr().err


@pytest.mark.e2e
@needs_torch
def test_a_split_benchmark_trains_inside_and_reports_in_and_out_of_distribution(tmp_path):
    out = tmp_path / "split"
    args = [*SMOKE, "--algos", "td3,dr", "--workers", "1", "--mesh", "3", "--out", str(out)]
    assert main([*args, "--split", "Extrapolation"]) == 0
    stored = json.loads((out / "benchmark.json").read_text())["protocol"]
    assert stored["split"] == "extrapolation:0.5"
    run = out / "runs" / "dr-invertedpendulum-1d-seed0"
    assert json.loads((run / "run.json").read_text())["config"]["split"] == "extrapolation:0.5"
    result = json.loads((run / "result.json").read_text())
    # mesh 3 over the 1d set: the centre is the inner box (ID), the two ends its shell (OOD)
    assert (result["points_id"], result["points_ood"]) == (1, 2)
    assert min(result["worst_case_id"], result["worst_case_ood"]) == result["worst_case"]
    ev = pd.read_parquet(out / "results" / "evaluations.parquet")
    assert ev.groupby("point")["in_distribution"].first().tolist() == [False, True, False]
    md = (out / "report" / "report.md").read_text()
    assert "## In and out of distribution" in md and "Split extrapolation:0.5" in md
    summary = json.loads((out / "report" / "summary.json").read_text())
    assert summary["results"]["invertedpendulum"]["dr"]["split"]["worst_case_ood"]["n_seeds"] == 1
    assert main([*args, "--split", "extrapolation:0.25"]) == 2  # another protocol: refused


@pytest.mark.e2e
@needs_torch
def test_committed_runs_resume_a_benchmark_on_a_fresh_machine(smoke, tmp_path, capsys):
    """What a reference produced in pieces relies on: the small files `collect_runs.py` keeps
    (no checkpoints) are enough for a new benchmark directory to skip the finished runs."""
    path = Path(__file__).resolve().parents[1] / "benchmarks" / "collect_runs.py"
    spec = importlib.util.spec_from_file_location("collect_runs", path)
    collect_runs = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(collect_runs)
    kept = tmp_path / "committed"
    assert len(collect_runs.collect(smoke, kept)) == 5
    assert not list(kept.rglob("checkpoint*"))
    fresh = tmp_path / "fresh"
    shutil.copytree(kept, fresh)
    capsys.readouterr()
    assert main([*SMOKE, "--out", str(fresh)]) == 0
    assert "(5 finished, 0 to run)" in capsys.readouterr().err
    assert (fresh / "report" / "report.md").exists()


@pytest.mark.e2e
@needs_torch
def test_a_benchmark_whose_runs_all_failed_says_so_without_a_report(tmp_path, capsys):
    out = tmp_path / "bench"
    algos = ["--algos", "td3,dr"]
    for algo in ("td3", "dr"):  # every run fails: a damaged checkpoint each
        run = out / "runs" / f"{algo}-invertedpendulum-1d-seed0"
        run.mkdir(parents=True)
        (run / "checkpoint.pt").write_bytes(b"not a checkpoint")
    assert main([*SMOKE, "--out", str(out), *algos]) == 1
    err = capsys.readouterr().err
    assert "2 run(s) failed" in err and "Traceback" not in err
    assert not (out / "report").exists()
    assert main(["report", str(out)]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and "no run has finished (2 failed" in lines[0], lines


@pytest.mark.e2e
@needs_torch
@pytest.mark.parametrize("copied", e2e_after_first(["result.json", "eval/episodes"]))
def test_a_file_copied_from_another_run_is_refused_by_name(tmp_path, capsys, copied):
    import shutil

    out = tmp_path / "bench"
    assert main([*SMOKE, "--out", str(out), "--algos", "td3", "--seeds", "0-1"]) == 0
    seed0 = out / "runs" / "td3-invertedpendulum-1d-seed0"
    seed1 = out / "runs" / "td3-invertedpendulum-1d-seed1"
    for path in seed1.glob(f"{copied}*"):  # the file and its seal: intact, but not seed 0's
        shutil.copy2(path, seed0 / path.relative_to(seed1))
    capsys.readouterr()
    assert main(["report", str(out)]) == 2
    line = capsys.readouterr().err.strip().splitlines()[-1]
    assert "copied from another run" in line and "seed0" in line, line
