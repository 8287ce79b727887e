"""The readings the results pages write in prose ("Reading it honestly", "What the table says"),
each checked against the shipped per-episode and per-run data it summarises."""

from __future__ import annotations

import sys
from pathlib import Path

import pandas as pd
from reading_helpers import RESULTS, ROOT, flat, mesh_points, nominal_curve, results, spaced

sys.path.insert(0, str(ROOT / "benchmarks"))

import results_page


def test_the_hopper_reading_of_where_the_agents_hop():
    folder = RESULTS / "hopper-200k"
    text = flat(folder / "README.md")
    hopping, falls = {}, []
    for run in sorted((folder / "runs").iterdir()):
        points = mesh_points(run)
        hopping[run.name] = int(((points["mean"] >= 2000) & (points.shortest >= 1000)).sum())
        falls.append(bool(points.loc[points["mean"].idxmin(), "fell"]))
    assert len(hopping) == 15 and all(falls)  # "every run's worst mesh point is a fall"
    dr = [v for k, v in hopping.items() if k.startswith("dr-")]
    assert f"is at most {max(hopping.values())} of the 1 000 points in any run" in text
    assert max(hopping.values()) == max(dr)  # DR holds the most
    assert f"(DR: {min(dr)} to {max(dr)} on every seed;" in text
    none = sum(v == 0 for v in hopping.values())
    assert f"{none} of the 15 runs have none)" in text
    # "every DR seed lies above every TD3 seed, yet with 3 seeds their intervals still overlap"
    avg = {a: v["average_case"] for a, v in results_page.per_seed(folder).items()}
    assert min(avg["dr"]) > max(avg["td3"])
    low, _ = results_page.t_interval(avg["dr"])
    assert low < results_page.t_interval(avg["td3"])[1]
    assert "every DR seed lies above every TD3 seed, yet with 3 seeds" in text


def _provenance(run: Path) -> tuple[str, str, str]:
    import json

    info = json.loads((run / "run.json").read_text())["provenance"]
    return info["commit"][:7], info["machine"]["cpu"], info["machine"]["simd"]


def test_the_hopper_page_names_each_runs_commit_and_cpu():
    # "TD3, DR and NR-MDP ... AMD EPYC ... X86_V4 ... at rrls commit d2fabcd; all three M2TD3
    # seeds and RARL seed 0 retrained on a 2-core AMD EPYC with AVX2 only (X86_V3) at rrls
    # commit d65188c, RARL seeds 1 and 2 on a 2-core Intel Xeon with AVX-512 (X86_V4) at e0436bc"
    folder = RESULTS / "hopper-200k"
    text = flat(folder / "README.md")
    runs = {run.name: _provenance(run) for run in (folder / "runs").iterdir()}
    for name, (commit, cpu, simd) in runs.items():
        algo, seed = name.split("-")[0], int(name[-1])
        if algo in ("td3", "dr", "nrmdp"):
            assert (commit, cpu, simd) == ("d2fabcd", "AMD EPYC", "X86_V4"), name
        elif algo == "m2td3" or seed == 0:
            assert (commit, cpu, simd) == ("d65188c", "AMD EPYC", "X86_V3"), name
        else:
            assert commit == "e0436bc" and "Xeon" in cpu and simd == "X86_V4", name
    assert "all three M2TD3 seeds and RARL seed 0 retrained on" in text
    assert "M2TD3 (all three seeds) and RARL seed 0 at `d65188c`" in text


def test_the_halfcheetah_reading_of_who_has_learned_to_run():
    import json

    from rrls.report.writer import paper_results

    folder = RESULTS / "halfcheetah"
    text = flat(folder / "README.md")
    nominal = {a: v["nominal"] for a, v in results_page.per_seed(folder).items()}
    # "TD3, DR, M2TD3 and NR-MDP: every seed's final nominal return is above 2 000 (TD3's above
    # 4 000)"; "RARL ... below zero on every seed, and no periodic evaluation ... reached 250"
    assert all(min(nominal[a]) > 2000 for a in ("td3", "dr", "m2td3", "nrmdp"))
    assert min(nominal["td3"]) > 4000 and max(nominal["rarl"]) < 0
    rarl = list((folder / "runs").glob("rarl-*"))
    assert rarl and all(nominal_curve(run).max() < 250 for run in rarl)
    assert "no periodic evaluation of any RARL seed reached 250" in text
    assert "where four of the five baselines learn to run" in text  # the title
    # the paper's RARL "near zero ... (worst case −211.8 ± 218.7, average case 206.7 ± 887.2)"
    paper = paper_results()
    for metric, name in (("raw_worst_case", "worst case"), ("raw_average_case", "average case")):
        mean, std = paper[metric]["rarl"]["halfcheetah"]
        assert abs(mean) < std
        assert f"{name} {mean:.1f} ± {std:.1f}".replace("-", "−") in text
    # "both robust-by-design methods beat TD3 in the worst case by more than 2 500"
    worst = {a: paper["raw_worst_case"][a]["halfcheetah"][0] for a in ("td3", "dr", "m2td3")}
    assert min(worst["dr"], worst["m2td3"]) - worst["td3"] > 2500
    assert "beat TD3 in the worst case by more than 2 500" in text
    # NR-MDP "scores more against its own adversary than without it, on every seed"; the paper's
    # Table 6 "(NR-MDP against its adversary 10 990 ± 474, its average case 1 388.9 ± 283.2)"
    for run in (folder / "runs").glob("nrmdp-*"):
        result = json.loads((run / "result.json").read_text())
        assert result["dynamic_mean"] > nominal_curve(run).iloc[-1], run.name
    dyn, avg = paper["dynamic"]["nrmdp"]["halfcheetah"], paper["raw_average_case"]["nrmdp"]
    mean = spaced(avg["halfcheetah"][0], ",.1f")
    assert f"10 990 ± 474, its average case {mean} ± " in text
    assert dyn == [10990.0, 474.0]
    # "NR-MDP seed 3 scored 6 379, 4 037 and 3 420 in its last three"
    last = nominal_curve(folder / "runs" / "nrmdp-halfcheetah-3d-seed3").iloc[-3:]
    a, b, c = (spaced(v) for v in last)
    assert f"NR-MDP seed 3 scored {a}, {b} and {c} in its last three" in text


def test_the_halfcheetah_normaliser_is_flagged_where_the_page_says():
    # "on the average case the two are within each other's 95 % intervals, so the report flags
    # that normaliser as unstable"
    folder = RESULTS / "halfcheetah"
    avg = {a: v["average_case"] for a, v in results_page.per_seed(folder).items()}
    td3, m2td3 = results_page.t_interval(avg["td3"]), results_page.t_interval(avg["m2td3"])
    assert td3[0] <= m2td3[1] and m2td3[0] <= td3[1]
    report = flat(folder / "report.md")
    assert "unstable normalisation**, halfcheetah average case" in report


def test_the_halfcheetah_page_states_the_versions_every_run_recorded():
    import json

    folder = RESULTS / "halfcheetah"
    versions = {
        json.dumps(json.loads(p.read_text())["versions"], sort_keys=True)
        for p in (folder / "runs").glob("*/result.json")
    }
    assert len(versions) == 1
    v = json.loads(versions.pop())
    stated = (
        f"torch {v['torch']}, MuJoCo {v['mujoco']}, Gymnasium {v['gymnasium']}, "
        f"numpy {v['numpy']}, Python {v['python']}"
    )
    assert stated in flat(folder / "README.md")


def test_the_halfcheetah_page_says_what_the_reference_refuses():
    # "refuses a benchmark whose mesh, episodes, set or physics differ from this reference's"
    from rrls.report.reference import (
        COMPARED,
        ReferenceError,
        check_compatible,
        load_reference,
    )

    assert set(COMPARED) == {"physics", "uncertainty", "mesh", "endpoint", "episodes"}
    ref = load_reference("halfcheetah")
    import json

    spec = json.loads((RESULTS / "halfcheetah" / "benchmark.json").read_text())
    check_compatible(ref, spec)  # its own benchmark fits
    spec["endpoint"] = True  # rrls's default mesh
    try:
        check_compatible(ref, spec)
    except ReferenceError as err:
        assert "endpoint" in str(err)
    else:
        raise AssertionError("rrls's default mesh (upper bounds included) was accepted")
    assert "refuses a benchmark whose mesh, episodes, set or physics differ" in flat(
        RESULTS / "halfcheetah" / "README.md"
    )


def test_the_presets_cpu_hours_stated_are_the_estimators():
    # docs/benchmark.md's preset table and `rrls benchmark --help`: "~11 CPU-hours" (hopper-200k),
    # "~27 CPU-hours" (halfcheetah), each what `--dry-run` estimates
    import argparse

    from rrls.benchmark.cpu_estimate import estimate
    from rrls.benchmark.grid import make_spec
    from rrls.cli.benchmark_command import add_parser

    doc = flat(ROOT / "docs" / "benchmark.md")
    helps = " ".join(add_parser(argparse.ArgumentParser().add_subparsers()).format_help().split())
    helps = helps.replace("CPU- hours", "CPU-hours")  # argparse wraps after a hyphen
    for preset in ("hopper-200k", "hopper", "halfcheetah"):
        hours = round(estimate(make_spec(preset), 2)["cpu_s"] / 3600)
        assert f"| ~{hours} CPU-hours (estimate;" in doc, preset
        assert f"{preset} (~{hours} CPU-hours" in helps, preset


def test_the_halfcheetah_runs_commits_train_alike():
    # "for every algorithm, the commits that trained its runs give the same weights and curves
    # bit for bit (same_training.csv). RARL differs at ca42dfc, which ... trained no RARL run"
    folder = RESULTS / "halfcheetah"
    same = pd.read_csv(folder / "same_training.csv")
    used: dict[str, set[str]] = {}
    for run in (folder / "runs").iterdir():
        commit = _provenance(run)[0]
        used.setdefault(run.name.split("-")[0], set()).add(commit)
    assert set(used["td3"]) == {"ca42dfc", "26468a0", "d6285a2"} <= set(same.commit)
    for algo, commits in used.items():
        rows = same[(same.algorithm == algo) & same.commit.isin(commits)]
        assert set(rows.commit) == commits, algo
        assert rows.weights_sha256.nunique() == 1 and rows.curves_sha256.nunique() == 1, algo
    # "and so does the later d77eecd, which the check also ran"
    later = same[same.commit == "d77eecd"].set_index("algorithm")
    for algo, row in same[same.commit == "26468a0"].set_index("algorithm").iterrows():
        assert later.loc[algo, "weights_sha256"] == row.weights_sha256, algo
    rarl = same[same.algorithm == "rarl"].set_index("commit").weights_sha256
    assert "ca42dfc" not in used["rarl"] and rarl["ca42dfc"] != rarl["26468a0"]
    assert "trained no RARL run" in flat(folder / "README.md")


def test_the_quick_pages_provenance_lists_the_references_commits():
    # "The reference's provenance.commits lists every commit that trained one of the 15 runs:
    # 827d334, 84de2a6, fb7996c and 827d334…+dirty"
    from rrls.report.reference import load_reference

    commits = load_reference("quick").provenance["commits"]
    short = sorted(c[:7] + ("…+dirty" if c.endswith("+dirty") else "") for c in commits)
    assert short == ["827d334", "827d334…+dirty", "84de2a6", "fb7996c"]
    text = flat(RESULTS / "quick" / "README.md")
    assert "15 runs: `827d334`, `84de2a6`, `fb7996c` and `827d334…+dirty`" in text


def test_the_hopper_td3_reading_against_the_authors_curves():
    # "At 50 k steps rrls's TD3 is where the authors' was; from 100 k steps on it falls behind
    # them" (rrls's nominal evaluations against the TD3 authors' evaluation mean ± std)
    import td3_sanity

    folder = RESULTS / "hopper-200k"
    _, evals = td3_sanity.td3_curves(folder)
    for step, (mean, std) in td3_sanity.AUTHORS.items():
        ours = evals[evals["step"] == step]["value"].mean()
        if step == 50_000:
            assert abs(ours - mean) < std
        else:
            assert ours < mean, step
    text = flat(folder / "README.md")
    assert "At 50 k steps rrls's TD3 is where the authors' was; from 100 k steps on" in text


def test_the_halfcheetah_reading_of_rarls_own_adversary():
    # "averages −8 687.5 on seed 4, its episodes between −25 591 and −523, against −433.3 to
    # −198.9 on seeds 0-3 ... far below anything on the static mesh"
    import json

    folder = RESULTS / "halfcheetah"
    text = flat(folder / "README.md")
    dyn, worst = {}, []
    for seed in range(5):
        run = folder / "runs" / f"rarl-halfcheetah-3d-seed{seed}"
        dyn[seed] = json.loads((run / "result.json").read_text())["dynamic_mean"]
        worst.append(mesh_points(run)["mean"].min())
    episodes = pd.read_csv(folder / "runs" / "rarl-halfcheetah-3d-seed4" / "dynamic.csv")["return"]

    def num(v: float, fmt: str) -> str:
        return format(v, fmt).replace(",", " ").replace("-", "−")

    assert f"averages {num(dyn[4], ',.1f')} on seed 4" in text
    assert f"between {num(episodes.min(), ',.0f')} and {num(episodes.max(), ',.0f')}" in text
    others = [dyn[s] for s in range(4)]
    assert f"against {num(min(others), ',.1f')} to {num(max(others), ',.1f')} on seeds 0-3" in text
    assert dyn[4] < 10 * min(worst)  # far below the static mesh's worst point of any seed


def test_the_halfcheetah_pages_counts_are_its_protocols():
    # "(5 episodes of the last policy)", "(5 000 episodes per run)", "for 3 000 steps at each"
    import json

    import same_training

    folder = RESULTS / "halfcheetah"
    text = flat(folder / "README.md")
    spec = json.loads((folder / "benchmark.json").read_text())
    assert f"({spec['eval_episodes']} episodes of the last policy)" in text
    for run in (folder / "runs").iterdir():  # a 3D mesh: mesh³ points × episodes
        assert len(pd.read_parquet(run / "eval" / "episodes.parquet")) == 5000, run.name
    assert spec["mesh"] ** 3 * spec["episodes"] == 5000 and "(5 000 episodes per run)" in text
    steps = same_training.SHORT[same_training.SHORT.index("--steps") + 1]
    assert f"for {int(steps):,} steps at each".replace(",", " ") in text


def test_the_halfcheetah_reading_of_what_survives_the_correction():
    """The worst-case claims of "What survives a correction for ten comparisons", from the
    shipped per-run values through the report's own pairwise test."""
    from rrls.report.pairwise import pairwise

    folder = RESULTS / "halfcheetah"
    text = flat(folder / "README.md")
    data = results_page.per_seed(folder)
    rows = {
        (r["a"], r["b"]): r
        for r in pairwise(
            {a: data[a]["worst_case"] for a in ("td3", "dr", "m2td3", "rarl", "nrmdp")}
        )
    }
    dr = rows["td3", "dr"]
    assert f"Welch p-value of {dr['p']:.3f} on its own" in text
    assert f"Holm's correction raises it to {dr['p_holm']:.3f}" in text
    smallest = min(r["p_holm"] for r in rows.values())
    assert smallest >= 0.05 and f"the smallest corrected p-value is {smallest:.3f}" in text
    assert {k for k, r in rows.items() if r["p_holm"] == smallest} == {
        ("dr", "rarl"),
        ("dr", "nrmdp"),
    }
    low, high = (spaced(-x) for x in reversed(dr["ci95"]))
    diff = spaced(-dr["diff"])
    assert f"DR ahead of TD3 by {diff} (95 % Welch interval [{low}, {high}])" in text


def test_the_halfcheetah_reading_of_the_rechecked_worst_case():
    """ "The worst case is partly episode noise, and less so for TD3": the per-seed moves and the
    orderings the corrected test resolves, from the runs' result.json."""
    import json

    from rrls.report.pairwise import pairwise

    folder = RESULTS / "halfcheetah"
    text = flat(folder / "README.md")
    moves: dict[str, list[float]] = {}
    rechecked: dict[str, list[float]] = {}
    for path in sorted((folder / "runs").glob("*/result.json")):
        r = json.loads(path.read_text())
        moves.setdefault(r["algorithm"], []).append(r["worst_case_rechecked"] - r["worst_case"])
        rechecked.setdefault(r["algorithm"], []).append(r["worst_case_rechecked"])
    assert sum(m > 0 for m in moves["dr"]) == 4
    assert f"(by up to {max(moves['dr']):.0f})" in text and "rises on four of its five" in text
    assert all(m > 0 for m in moves["m2td3"]) and "M2TD3's on all five" in text
    bound = max(abs(m) for a in ("td3", "rarl", "nrmdp") for m in moves[a])
    assert f"move within ±{bound:.0f}" in text
    resolved = {
        (r["a"], r["b"])
        for r in pairwise({a: rechecked[a] for a in ("td3", "dr", "m2td3", "rarl", "nrmdp")})
        if r["p_holm"] < 0.05
    }
    assert resolved == {("td3", "dr"), ("dr", "rarl"), ("dr", "nrmdp")}
    assert "DR's lead over TD3, RARL and NR-MDP survives Holm's correction" in text


def test_the_evaluation_docs_examples_of_the_recheck_are_the_shipped_runs():
    """docs/evaluation.md's "when they disagree" and "when the two agree", from the references'
    result.json files."""
    text = flat(ROOT / "docs" / "evaluation.md")
    dr = [r for r in results(RESULTS / "halfcheetah") if r["algorithm"] == "dr"]
    assert len(dr) == 5
    rechecked = sum(r["worst_case_rechecked"] for r in dr) / 5
    minimum = sum(r["worst_case"] for r in dr) / 5
    said = f"is {spaced(rechecked)} against a mean minimum of {spaced(minimum)}"
    assert rechecked - minimum > 300 and said in text
    moves = [abs(r["worst_case_rechecked"] - r["worst_case"]) for r in results(RESULTS / "hopper")]
    assert len(moves) == 25 and max(moves) < 43 <= max(moves) + 1
    assert "no run's recheck moves by 43 or more" in text
