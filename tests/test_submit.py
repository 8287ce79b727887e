"""rrls submit and reference results: a policy trained elsewhere becomes a column of the report;
reference files normalise benchmarks without baselines and are refused under another protocol.

The benchmark here is the smoke protocol (InvertedPendulum 1D, mesh 2 x 1 episode) with two
"trained" runs written directly (fixed linear controllers as TD3 and M2TD3): seconds, no
training. ``tests/test_experiments.py`` submits into a real smoke benchmark.
"""

from __future__ import annotations

import json
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from rrls.benchmark.grid import RunKey, make_spec
from rrls.benchmark.store import build_store, write_result
from rrls.cli import main
from rrls.evaluation import BatchInvariant, MLPPolicy, evaluate
from rrls.files import atomic_write_json
from rrls.report.exported import export_reference
from rrls.report.reference import (
    PAPER_PHYSICS,
    ReferenceError,
    load_reference,
    paper_reference_from_results,
)
from rrls.report.writer import make_report, paper_results
from rrls.submissions import submit
from rrls.submissions.steps import SubmitError, create_benchmark

pytest.importorskip("scipy")


def linear(*gains: float) -> BatchInvariant:
    """A linear controller of InvertedPendulum (batch-invariant: exact episodes)."""
    k = np.asarray(gains, dtype=float)
    return BatchInvariant(lambda obs: np.clip((obs @ k)[:, None], -3.0, 3.0))


BASELINES = {"td3": linear(1.0, 0.0, 0.0, 0.0), "m2td3": linear(0.0, 5.0, 0.0, 1.0)}


def make_benchmark(root: Path) -> Path:
    """A smoke-protocol benchmark whose TD3 and M2TD3 runs are fixed controllers."""
    spec = replace(make_spec("smoke"), algos=tuple(BASELINES))
    atomic_write_json(root / "benchmark.json", spec.to_json())
    for algo, policy in BASELINES.items():
        run = root / "runs" / RunKey(algo, "invertedpendulum", 0).name(spec.uncertainty)
        res = evaluate(
            policy, "invertedpendulum", "1d", spec.mesh, spec.episodes, spec.eval_seed, 1,
            out_dir=run / "eval",
        )  # fmt: skip
        write_result(
            run,
            {
                "algorithm": algo,
                "task": "invertedpendulum",
                "uncertainty": "1d",
                "seed": 0,
                "steps": spec.steps,
                "worst_case": res.worst_case,
                "average_case": res.average_case,
                "versions": res.config["versions"],
            },
        )
    return root


@pytest.fixture
def bench(tmp_path) -> Path:
    return make_benchmark(tmp_path / "bench")


def report(root: Path, **kw) -> dict:
    build_store(root)
    make_report(root, plots=False, **kw)
    return json.loads((root / "report" / "summary.json").read_text())


def test_submitted_callable_is_a_column_of_every_table(bench):
    mine = linear(0.5, 8.0, 0.5, 1.0)
    done = submit(bench, "my-method", "invertedpendulum", 0, mine, workers=1)
    assert done.evaluated and done.run_dir.name == "my-method-invertedpendulum-1d-seed0"
    # evaluated exactly as the baselines: same mesh points and episode seeds
    ev = pd.read_parquet(build_store(bench) / "evaluations.parquet")
    seeds = {a: ev[ev["algorithm"] == a]["episode_seed"].tolist() for a in ev["algorithm"]}
    assert seeds["my-method"] == seeds["td3"] == seeds["m2td3"]
    direct = evaluate(mine, "invertedpendulum", "1d", mesh=2, episodes=1, seed=0)
    assert done.worst_case == direct.worst_case and done.average_case == direct.average_case

    summary = report(bench)
    cell = summary["results"]["invertedpendulum"]["my-method"]
    td3 = summary["results"]["invertedpendulum"]["td3"]["worst_case"]["mean"]
    m2 = summary["results"]["invertedpendulum"]["m2td3"]["worst_case"]["mean"]
    expected = (direct.worst_case - td3) / abs(m2 - td3)
    assert cell["normalised"]["worst_case"]["mean"] == pytest.approx(expected)
    assert summary["aggregate"]["my-method"]["poi_over_td3_worst_case"]["value"] == 1.0
    assert summary["normalisation"]["invertedpendulum"]["worst_case"] == "benchmark"
    assert summary["submitted"][0]["policy_kind"] == "callable"
    for name in ("raw_worst_case", "raw_average_case", "normalised_worst_case"):
        table = pd.read_csv(bench / "report" / "tables" / f"{name}.csv")
        assert "my-method" in set(table["algorithm"])
    md = (bench / "report" / "report.md").read_text()
    # no budget stated: marked, as a row whose budget differs from the benchmark's
    assert "| my-method (submitted)‡ |" in md and "## Submitted policies" in md
    runs = pd.read_parquet(bench / "results" / "runs.parquet")
    assert dict(zip(runs["algorithm"], runs["source"]))["my-method"] == "submitted"


def test_submit_is_its_three_steps_check_evaluate_install(bench):
    from rrls.submissions.steps import (
        Entry,
        check_submission,
        evaluate_submission,
        install_submission,
    )

    def files() -> list[Path]:
        return sorted(p.relative_to(bench) for p in bench.rglob("*"))

    entry = Entry("stepwise", "invertedpendulum", 0, linear(0.5, 8.0, 0.5, 1.0))
    before = files()
    checked = check_submission(bench, entry)
    assert files() == before  # checked: nothing run, nothing written
    assert checked.final == bench / "runs" / "stepwise-invertedpendulum-1d-seed0"
    staged = evaluate_submission(checked, workers=1)
    assert staged.dir.is_dir() and not checked.final.exists()  # evaluated, not installed
    done = install_submission(checked, staged)
    assert done.evaluated and done.run_dir == checked.final and not staged.dir.exists()
    again = submit(bench, "stepwise", "invertedpendulum", 0, entry.policy, workers=1)
    assert not again.evaluated and again.worst_case == done.worst_case
    after = files()
    with pytest.raises(SubmitError, match="built-in algorithm"):
        check_submission(bench, replace(entry, algo="td3"))
    assert files() == after  # a refusal changes nothing


def test_module_attribute_submit_records_the_module_and_its_hash(bench, tmp_path, monkeypatch):
    pkg = tmp_path / "userpkg"
    pkg.mkdir()
    source = (
        "import numpy as np\n"
        "def act(obs):\n"
        "    return np.clip(obs[:, 1:2] * 5.0 + obs[:, 3:4], -3, 3)\n"
    )
    (pkg / "controller.py").write_text(source)
    monkeypatch.syspath_prepend(str(tmp_path))
    code = main(
        ["submit", str(bench), "--algo", "ctrl", "--task", "invertedpendulum", "--seed", "3"]
        + ["userpkg.controller:act", "--workers", "1"]
    )
    assert code == 0
    result = json.loads(
        (bench / "runs" / "ctrl-invertedpendulum-1d-seed3" / "result.json").read_text()
    )
    sub = result["submitted"]
    assert sub["kind"] == "module-attribute" and sub["source"] == "userpkg.controller:act"
    import hashlib

    assert sub["sha256"] == hashlib.sha256(source.encode()).hexdigest()
    assert result["seed"] == 3 and result["algorithm"] == "ctrl"
    sys.modules.pop("userpkg.controller", None)


def test_sb3_zip_submit(bench, tmp_path):
    sb3 = pytest.importorskip("stable_baselines3")
    import gymnasium as gym

    env = gym.make("rrls/robust-invertedpendulum-v0")
    model = sb3.TD3("MlpPolicy", env, policy_kwargs={"net_arch": [8]}, seed=0, device="cpu")
    model.save(tmp_path / "agent.zip")
    done = submit(bench, "sb3-td3", "invertedpendulum", 0, str(tmp_path / "agent.zip"), workers=1)
    sub = done.result["submitted"]
    import hashlib

    assert sub["kind"] == "sb3-zip"
    assert sub["sha256"] == hashlib.sha256((tmp_path / "agent.zip").read_bytes()).hexdigest()
    # the same numbers as the model itself, evaluated directly
    direct = evaluate(model, "invertedpendulum", "1d", mesh=2, episodes=1, seed=0)
    assert done.worst_case == direct.worst_case
    assert "sb3-td3" in report(bench)["algorithms"]


def test_wrong_shapes_are_refused_before_any_episode(bench, capsys):
    hopper = MLPPolicy.random(obs_dim=11, act_dim=3, hidden=(8,))
    with pytest.raises(SubmitError, match=r"\(B, 11\).*\(B, 3\).*\(B, 4\).*\(B, 1\)"):
        submit(bench, "hop", "invertedpendulum", 0, hopper)
    two_actions = BatchInvariant(lambda obs: np.zeros((len(obs), 2)))
    with pytest.raises(SubmitError, match=r"actions \(B, 2\).*actions \(B, 1\)"):
        submit(bench, "two", "invertedpendulum", 0, two_actions)
    assert not (bench / "runs" / "hop-invertedpendulum-1d-seed0").exists()
    assert (
        not list((bench / "submissions").glob(".staging/*"))
        if (bench / "submissions").exists()
        else True
    )
    hopper.save(bench / "hopper.npz")
    code = main(["submit", str(bench), "--algo", "hop", "--task", "invertedpendulum"]
                + ["--seed", "0", str(bench / "hopper.npz")])  # fmt: skip
    err = capsys.readouterr().err.strip()
    assert code == 2 and len(err.splitlines()) == 1
    assert "(B, 11)" in err and "(B, 4)" in err


def test_resubmit_same_policy_is_a_no_op_another_is_refused_unless_overwrite(bench):
    first = linear(0.0, 5.0, 0.0, 0.0)
    submit(bench, "mine", "invertedpendulum", 0, first, workers=1)
    again = submit(bench, "mine", "invertedpendulum", 0, linear(0.0, 5.0, 0.0, 0.0), workers=1)
    assert not again.evaluated
    other = linear(0.5, 8.0, 0.5, 1.0)
    with pytest.raises(SubmitError, match="--overwrite"):
        submit(bench, "mine", "invertedpendulum", 0, other, workers=1)
    replaced = submit(bench, "mine", "invertedpendulum", 0, other, overwrite=True, workers=1)
    assert replaced.evaluated and replaced.worst_case == 1000.0
    assert json.loads((replaced.run_dir / "result.json").read_text())["worst_case"] == 1000.0


@pytest.mark.parametrize("name", ["td3", "M2TD3", "nr-mdp", "paper", "9lives", "a b"])
def test_names_of_built_in_algorithms_and_bad_names_are_refused(bench, name, capsys):
    code = main(["submit", str(bench), "--algo", name, "--task", "invertedpendulum", "--seed", "0"]
                + ["x.npz"])  # fmt: skip
    err = capsys.readouterr().err
    assert code == 2 and len(err.strip().splitlines()) == 1
    assert ("reserved: td3, dr, rarl, nrmdp, m2td3" in err) or ("not a valid" in err)


def test_task_outside_the_benchmark_and_missing_benchmark_are_refused(bench, tmp_path):
    with pytest.raises(SubmitError, match="its tasks: invertedpendulum"):
        submit(bench, "mine", "hopper", 0, MLPPolicy.random(11, 3, (8,)))
    with pytest.raises(SubmitError, match="not a benchmark directory"):
        submit(tmp_path / "nowhere", "mine", "invertedpendulum", 0, linear(1, 1, 1, 1))


def test_adversary_adds_the_dynamic_evaluation(bench):
    adversary = MLPPolicy.random(obs_dim=4, act_dim=1, hidden=(8,), seed=3)  # 1d set: 1 param
    done = submit(bench, "mine", "invertedpendulum", 0, linear(0, 5, 0, 1), adversary, workers=1)
    assert done.result["dynamic_env"] == "rrls/robust-invertedpendulum-adversarial-1d-v0"
    assert done.result["submitted"]["adversary"]["game"] == "adversarial"
    summary = report(bench)
    assert summary["results"]["invertedpendulum"]["mine"]["dynamic"]["n_seeds"] == 1
    assert (
        "| mine (submitted)‡ |"  # no budget stated
        in (bench / "report" / "report.md").read_text().split("Dynamic evaluation")[1]
    )
    wrong = MLPPolicy.random(obs_dim=4, act_dim=3, hidden=(8,))
    with pytest.raises(SubmitError, match="adversary"):
        submit(bench, "other", "invertedpendulum", 0, linear(0, 5, 0, 1), wrong)


def test_a_tc_benchmarks_adversary_sees_psi_the_state_and_the_action(tmp_path):
    # TC-RMDP's game (--rate-limit): the omniscient adversary observes [ψ01, s, a]
    root = tmp_path / "tc"
    spec = create_benchmark(root, "smoke", ("invertedpendulum",), rate_limit=0.01)
    assert spec.rate_game == "tc"
    dim = 1 + 4 + 1  # the smoke set's one parameter, the state, the protagonist's action
    adversary = MLPPolicy.random(obs_dim=dim, act_dim=1, hidden=(8,), seed=3)
    done = submit(root, "mine", "invertedpendulum", 0, linear(0, 5, 0, 1), adversary, workers=1)
    assert (
        "rate_limit=0.01, rate_game=tc, observe=vanilla, omniscient=True"
        in (done.result["dynamic_env"])
    )
    blind = MLPPolicy.random(obs_dim=4, act_dim=1, hidden=(8,), seed=3)
    with pytest.raises(SubmitError, match=r"adversary .* observations \(B, 6\)"):
        submit(root, "other", "invertedpendulum", 0, linear(0, 5, 0, 1), blind)


# --- reference results ------------------------------------------------------------------------
def test_exported_reference_normalises_a_benchmark_without_baselines(bench, tmp_path):
    report(bench)
    ref_path = export_reference(bench, tmp_path / "ref.json", label="lab A").path
    empty = tmp_path / "mine"
    mine = linear(0.0, 5.0, 0.0, 0.0)
    submit(empty, "mine", "invertedpendulum", 0, mine, preset="smoke", workers=1)
    summary = report(empty, reference=ref_path)
    ref = load_reference(ref_path)
    td3 = ref.mean("invertedpendulum", "1d", "td3", "worst_case")
    m2 = ref.mean("invertedpendulum", "1d", "m2td3", "worst_case")
    v = summary["results"]["invertedpendulum"]["mine"]["worst_case"]["mean"]
    got = summary["results"]["invertedpendulum"]["mine"]["normalised"]["worst_case"]["mean"]
    assert got == pytest.approx((v - td3) / abs(m2 - td3))
    assert summary["normalisation"]["invertedpendulum"]["worst_case"] == "reference"
    assert summary["reference"]["label"] == "lab A"
    assert summary["aggregate"]["mine"]["poi_over_td3_worst_case"]["n_tasks"] == 1
    md = (empty / "report" / "report.md").read_text()
    assert "the reference **lab A**" in md and "## Reference: lab A" in md
    # where the numbers came from: preset, budget, versions, commits, machines of the runs
    prov = json.loads(Path(ref_path).read_text())["provenance"]
    assert prov["preset"] == "smoke" and prov["steps"] == 300 and prov["runs"] == len(BASELINES)
    assert prov["versions"]["mujoco"] and prov["versions"]["rrls"] and ref.provenance == prov
    # CSV holds the same reference
    ref.save(tmp_path / "ref.csv")
    assert load_reference(tmp_path / "ref.csv").rows == ref.rows


@pytest.mark.parametrize(
    "field, value, needle",
    [
        ("mesh", 10, "mesh: 10 there, 2 here"),
        ("episodes", 5, "episodes: 5 there, 1 here"),
        ("physics", PAPER_PHYSICS, "physics: 'paper' there, 'v5' here"),
    ],
)
def test_reference_of_another_protocol_is_refused(bench, tmp_path, capsys, field, value, needle):
    report(bench)
    ref = export_reference(bench, tmp_path / "ref.json")
    data = json.loads((tmp_path / "ref.json").read_text())
    data[field] = value
    (tmp_path / "bad.json").write_text(json.dumps(data))
    with pytest.raises(ReferenceError, match=needle):
        make_report(bench, plots=False, reference=tmp_path / "bad.json")
    assert (
        main(["report", str(bench), "--no-plots", "--reference", str(tmp_path / "bad.json")]) == 2
    )
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and needle in err
    assert ref.rows  # the exported file itself is accepted
    make_report(bench, plots=False, reference=tmp_path / "ref.json")


def test_reference_of_another_set_is_refused(bench, tmp_path):
    report(bench)
    export_reference(bench, tmp_path / "ref.json")
    data = json.loads((tmp_path / "ref.json").read_text())
    for row in data["rows"]:
        row["uncertainty"] = "2d"
    (tmp_path / "bad.json").write_text(json.dumps(data))
    with pytest.raises(ReferenceError, match=r"uncertainty: \['2d'\] there, '1d' here"):
        make_report(bench, plots=False, reference=tmp_path / "bad.json")


def test_shipped_paper_reference_is_the_papers_tables_on_other_physics(bench):
    ref = load_reference("paper")
    assert ref.label == "paper, other physics" and ref.physics == PAPER_PHYSICS
    assert ref.to_json() == paper_reference_from_results(paper_results()).to_json()
    assert ref.mean("hopper", "3d", "m2td3", "worst_case") == 273.6  # paper Table 7
    with pytest.raises(ReferenceError, match="physics: 'paper' there"):
        make_report(bench, plots=False, reference="paper")


def test_damaged_reference_is_named(tmp_path):
    (tmp_path / "x.json").write_text("{not json")
    with pytest.raises(ReferenceError, match="x.json.*invalid JSON"):
        load_reference(tmp_path / "x.json")
    (tmp_path / "y.json").write_text(json.dumps({"format": "other"}))
    with pytest.raises(ReferenceError, match="format"):
        load_reference(tmp_path / "y.json")


def test_create_benchmark_has_the_presets_protocol(tmp_path):
    spec = create_benchmark(tmp_path / "b", "quick", ("invertedpendulum",))
    assert spec.algos == () and spec.binding_fields() == make_spec("quick").binding_fields()


def test_shipped_hopper_reference_fits_the_hopper_preset(tmp_path):
    ref = load_reference("hopper-200k")
    assert ref.physics == "v5" and ref.steps == 200_000 and ref.sets == ["3d"]
    assert set(ref.algorithms()) == {"td3", "dr", "rarl", "nrmdp", "m2td3"}
    static = [r for r in ref.rows if r["metric"] in ("worst_case", "average_case")]
    assert static and all(len(r["values"]) == r["n_seeds"] == 3 for r in static)
    assert ref.provenance["preset"] == "hopper" and ref.provenance["hidden"] == [256, 256]
    assert ref.provenance["machines"] and ref.provenance["versions"]["torch"]
    spec = create_benchmark(tmp_path / "b", "hopper-200k", ("hopper",))
    from rrls.report.reference import check_compatible

    check_compatible(ref, spec.to_json())  # same physics, set, mesh, episodes


def test_shipped_halfcheetah_reference_fits_its_preset_and_counts_its_runs(tmp_path):
    # produced in pieces, now complete: its label and notes say so, as its rows do
    ref = load_reference("halfcheetah")
    assert ref.physics == "v5" and ref.steps == 300_000 and ref.sets == ["3d"]
    assert ref.episodes == 5 and ref.mesh == 10 and ref.endpoint is False  # the paper's mesh
    static = [r for r in ref.rows if r["metric"] == "worst_case"]
    runs = sum(r["n_seeds"] for r in static)
    # complete: 5 seeds of each of the five, labelled as the paper's reduced budget
    assert runs == 25 and "5 of its 10 seeds" in ref.label and "reduced budget" in ref.label
    assert "all 25 of the preset's runs (5 seeds of each algorithm)" in ref.notes
    assert ref.provenance["preset"] == "halfcheetah" and ref.provenance["runs"] == runs
    spec = create_benchmark(tmp_path / "b", "halfcheetah", ("halfcheetah",))
    from rrls.report.reference import check_compatible

    check_compatible(ref, spec.to_json())


def test_shipped_quick_reference_fits_the_quick_preset(tmp_path):
    ref = load_reference("quick")
    assert ref.physics == "v5" and ref.steps == 30_000 and ref.sets == ["1d"]
    assert set(ref.algorithms()) == {"td3", "dr", "rarl", "nrmdp", "m2td3"}
    assert all(len(r["values"]) == r["n_seeds"] == 3 for r in ref.rows)
    # where it came from, and a TD3 that learned: its average case is over 900 on every seed
    assert ref.provenance["preset"] == "quick" and ref.provenance["hidden"] == [64, 64]
    assert ref.provenance["machines"] and ref.provenance["versions"]["torch"]
    assert min(ref.cell("invertedpendulum", "1d", "td3", "average_case")["values"]) > 900
    spec = create_benchmark(tmp_path / "b", "quick", ("invertedpendulum",))
    from rrls.report.reference import check_compatible

    check_compatible(ref, spec.to_json())  # no error: same physics, set, mesh, episodes
