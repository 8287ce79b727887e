"""The Hopper reference's page ("Reading it honestly", the physics section, the sentence under the
paper block), each statement checked against the 25 runs' files and the report's own tests."""

from __future__ import annotations

import sys

import pandas as pd
from reading_helpers import RESULTS, ROOT, flat, mesh_points, nominal_curve, spaced

from rrls.algorithms import display_name

sys.path.insert(0, str(ROOT / "benchmarks"))

import results_page


def test_the_hopper_runs_commits_train_alike():
    # "every execution of every run shipped, at N commits: for each algorithm, the commits that
    # trained its runs give the same weights and curves bit for bit (same_training.csv)"
    from rrls.rundir import executions, read_run_json

    folder = RESULTS / "hopper"
    same = pd.read_csv(folder / "same_training.csv")
    used: dict[str, set[str]] = {}
    for run in (folder / "runs").iterdir():
        commits = {e["commit"][:7] for e in executions(read_run_json(run)) if e.get("commit")}
        used.setdefault(run.name.split("-")[0], set()).update(commits)
    every = set().union(*used.values())
    assert len(used) == 5 and every <= set(same.commit)
    for algo, commits in used.items():
        rows = same[(same.algorithm == algo) & same.commit.isin(commits)]
        assert set(rows.commit) == commits, algo
        assert rows.weights_sha256.nunique() == 1 and rows.curves_sha256.nunique() == 1, algo
    text = flat(folder / "README.md")
    assert f"every commit in the runs' `provenance.executions` ({len(every)} commits:" in text
    listed = text.split(f"({len(every)} commits: ", 1)[1].split(")", 1)[0]
    assert sorted(c.strip("` ") for c in listed.replace(" and ", ", ").split(", ")) == sorted(every)


def _hopper_mesh():
    """The Hopper grid's mesh points, (1 000, 3): friction, torso mass, thigh mass."""
    from rrls.benchmark import benchfile

    return benchfile.read_spec(RESULTS / "hopper").protocol.plan("hopper").points


def _hopper_runs() -> pd.DataFrame:
    """Per Hopper run: its scores, its final nominal return, its worst mesh point (where, whether
    every episode there fell, the longest of them), how many points it survives everywhere, and
    whether it scores more at the set's heaviest torso (thigh) mass than at its lightest."""
    import json

    folder = RESULTS / "hopper"
    points = _hopper_mesh()
    rows = []
    for run in sorted((folder / "runs").iterdir()):
        at = mesh_points(run)
        worst = at["mean"].idxmin()
        heavier = {}  # the return at the set's heaviest against its lightest torso (thigh) mass,
        for dim, name in ((1, "torso"), (2, "thigh")):  # the other two averaged: the figure
            curve = pd.Series(at["mean"].to_numpy()).groupby(points[:, dim]).mean()
            heavier[f"heavier_{name}"] = bool(curve.iloc[-1] > curve.iloc[0])
        result = json.loads((run / "result.json").read_text())
        rows.append(
            {
                "algorithm": result["algorithm"],
                "seed": result["seed"],
                "move": result["worst_case_rechecked"] - result["worst_case"],
                "recheck": (result["recheck"]["worst"], result["recheck"]["episodes"]),
                "episodes": int(at.episodes.min()),
                "average": result["average_case"],
                "nominal": nominal_curve(run).iloc[-1],
                "fell": bool(at.loc[worst, "fell"]),
                "longest": int(at.loc[worst, "longest"]),
                "friction": points[worst][0],
                "torso": points[worst][1],
                "thigh": points[worst][2],
                "survived": int((at.shortest >= 1000).sum()),
                **heavier,
            }
        )
    return pd.DataFrame(rows)


def test_the_hopper_reading_of_its_worst_points_and_nominal_returns():
    runs = _hopper_runs()
    text = flat(RESULTS / "hopper" / "README.md")
    n = len(runs)
    assert f"What the {n} runs shipped so far say" in text or f"What the {n} runs say" in text
    # every worst point is a fall, early ("all 5 episodes"); the recheck ("20 fresh episodes at
    # each run's 10 lowest points") moves it little
    assert runs.fell.all() and (runs.episodes == 5).all()
    assert set(runs.recheck) == {(10, 20)}
    assert f"within {runs.longest.max()} of the 1 000 steps" in text
    assert f"within {int(runs.move.abs().max() + 1)} of the paper's statistic on every run" in text
    assert f"and within 10 on {int((runs.move.abs() <= 10).sum())} of the {n}" in text
    # DR and M2TD3: the lowest friction under a heavy torso; the others spread over the set
    robust = runs[runs.algorithm.isin(["dr", "m2td3"])]
    assert (robust.friction == runs.friction.min()).all() and runs.friction.min() == 0.1
    assert f"torso mass of {robust.torso.min():.2f} or more" in text
    assert f"(the mesh's largest: {_hopper_mesh().max(axis=0)[1]:.2f})" in text
    others = runs[~runs.algorithm.isin(["dr", "m2td3"])]
    assert others.friction.nunique() > 1 and others.torso.nunique() > 1
    seed0 = runs[(runs.algorithm == "nrmdp") & (runs.seed == 0)].iloc[0]
    assert seed0.torso == seed0.thigh == 0.1  # "NR-MDP seed 0's at torso and thigh masses of 0.1"
    # the points survived everywhere
    best = runs.loc[runs.survived.idxmax()]
    rest = runs.drop(index=runs.survived.idxmax())
    assert f"at most {rest.survived.max()} of the 1 000 on every run but one" in text
    assert f"(M2TD3 seed {best.seed}: {best.survived})" in text and best.algorithm == "m2td3"
    zero = runs[runs.survived == 0]
    assert len(zero) == 1 and (zero.algorithm.iloc[0], zero.seed.iloc[0]) == ("rarl", 1)
    # the nominal return against the average case
    raw = (RESULTS / "hopper" / "README.md").read_text()
    for name, part in (("torso", "torsomass"), ("thigh", "thighmass")):
        value = raw.split(f"| hopper | {part} | ", 1)[1].split(" | ")[1]
        assert f"{name} ({value})" in text  # the set's table: the model's own mass, outside
    on_nominal = runs[runs.algorithm.isin(["td3", "nrmdp"])].nominal
    on_set = runs[runs.algorithm.isin(["dr", "m2td3", "rarl"])].nominal
    assert on_nominal.min() > 1700 and on_set.max() < on_nominal.min()
    assert f"end between {on_set.min():.0f} and {on_set.max():.0f} on the nominal model" in text
    mean = runs.groupby("algorithm").average.mean()
    assert mean["dr"] > mean["td3"]
    dr, td3 = (spaced(mean[a]) for a in ("dr", "td3"))
    assert f"mean average case over the set ({dr}) is above TD3's ({td3})" in text


def test_the_hopper_reading_of_what_the_paper_physics_moves():
    text = flat(RESULTS / "hopper" / "README.md")
    runs = pd.read_csv(RESULTS / "hopper" / "paper_physics.csv")
    runs["worst"] = runs.worst_case_paper - runs.worst_case_v5
    runs["average"] = runs.average_case_paper - runs.average_case_v5
    cheetah = pd.read_csv(RESULTS / "halfcheetah" / "paper_physics.csv")
    moved = (cheetah.average_case_paper - cheetah.average_case_v5).groupby(cheetah.algorithm)
    assert moved.mean().abs().max() < 30  # "no algorithm's average case moved by 30 on average"
    rising = runs[runs.algorithm.isin(["td3", "dr"])]
    assert (rising.average > 0).all()
    top = runs.loc[runs.average.idxmax()]
    assert f"(by up to {top.average:.0f}, DR seed {top.seed})" in text and top.algorithm == "dr"
    for algo in ("m2td3", "rarl"):
        mostly = runs[runs.algorithm == algo]
        down = mostly[mostly.average < 0]
        up, name = len(mostly) - len(down), display_name(algo)
        assert f"on {up} of {name}'s {len(mostly)}" in text
        for seed, change in zip(down.seed, down.average):
            assert f"{name}'s {len(mostly)} (seed {seed}'s falls by {-change:.0f})" in text
    nrmdp = runs[runs.algorithm == "nrmdp"]
    falls = nrmdp[nrmdp.average < 0]
    assert (
        f"falls on {len(falls)} of NR-MDP's {len(nrmdp)} runs (by up to {-falls.average.min():.0f})"
        in text
    )
    assert (runs[runs.algorithm.isin(["td3", "dr", "m2td3"])].worst > 0).all()
    still, moving = nrmdp[nrmdp.worst.abs() < 14], nrmdp[nrmdp.worst.abs() >= 14]
    assert f"moves by less than 14 on {len(still)} of NR-MDP's {len(nrmdp)} runs" in text
    for seed, change in zip(moving.seed, moving.worst):
        assert f"seed {seed}'s {'rises' if change > 0 else 'falls'} by {abs(change):.0f}" in text
    # "each order by mean swaps one pair: in the worst case DR, whose runs rise most, moves above
    # M2TD3; in the average case M2TD3 moves above NR-MDP, whose runs fall most"
    for column, (up, down) in (
        ("worst_case", ("dr", "m2td3")),
        ("average_case", ("m2td3", "nrmdp")),
    ):
        means = runs.groupby("algorithm")[[f"{column}_v5", f"{column}_paper"]].mean()
        v5, paper = (list(means[c].sort_values(ascending=False).index) for c in means.columns)
        i = v5.index(down)
        assert v5[i + 1] == up and paper == v5[:i] + [up, down] + v5[i + 2 :], column
    change = runs.groupby("algorithm")[["worst", "average"]].mean()
    assert change.worst.idxmax() == "dr" and change.average.idxmin() == "nrmdp"
    assert "Each order by mean swaps one pair: in the worst case DR, whose runs rise most" in text
    assert "in the average case M2TD3 moves above NR-MDP, whose runs fall most" in text


def test_the_hopper_sentence_under_the_paper_block_is_the_physics_files():
    """What the paper's physics changes in the verdicts beside the paper's row, read from
    paper_physics.csv through the same Welch + Holm test as the blocks."""
    import page_checks

    from rrls.report.writer import paper_results

    folder = RESULTS / "hopper"
    text = flat(folder / "README.md")
    data = page_checks.read_physics(folder / "paper_physics.csv")
    paper = paper_results()

    def phrase(metric: str, physics: str) -> str:
        gained = page_checks.resolved({a: by[f"{metric}_{physics}"] for a, by in data.items()})
        published = {a: v["hopper"][0] for a, v in paper[f"raw_{metric}"].items()}
        assert all(published[a] > published[b] for a, b in gained)  # each the paper's way
        label = metric.replace("_case", "-case")
        if not gained:
            return f"none of the paper's {label} orderings"
        names = [f"{display_name(a)} > {display_name(b)}" for a, b in gained]
        listed = names[0] if len(names) == 1 else ", ".join(names[:-1]) + " and " + names[-1]
        return f"{len(gained)} of the paper's {label} orderings ({listed})"

    runs = pd.read_csv(folder / "paper_physics.csv")
    for metric in ("worst_case", "average_case"):  # "score higher on most runs"
        assert (runs[f"{metric}_paper"] > runs[f"{metric}_v5"]).mean() > 0.5
    assert (
        "score higher on most runs, and there the corrected test reproduces "
        f"{phrase('average_case', 'paper')} and {phrase('worst_case', 'paper')}; on rrls's "
        f"physics it reproduces {phrase('average_case', 'v5')} and {phrase('worst_case', 'v5')}"
    ) in text


def test_the_hopper_reading_of_the_heavy_end_of_the_set():
    """Per run, the return averaged over the other two parameters at the set's heaviest and
    lightest torso (and thigh) mass of the mesh, as the page's figure draws it."""
    text = flat(RESULTS / "hopper" / "README.md")
    mesh = _hopper_mesh()
    heavier = _hopper_runs().groupby("algorithm")[["heavier_torso", "heavier_thigh"]].sum()
    more = {name: heavier[f"heavier_{name}"] for name in ("torso", "thigh")}
    heaviest = {name: f"{mesh[:, dim].max():.2f}" for dim, name in ((1, "torso"), (2, "thigh"))}
    assert f"heaviest torso mass ({heaviest['torso']}) than at its lightest (0.1)" in text
    assert f"at the heaviest thigh mass ({heaviest['thigh']}) against the lightest" in text
    for name in ("torso", "thigh"):
        assert more[name]["td3"] == 5 and more[name]["nrmdp"] == 4  # "every TD3 seed and 4 of 5"
        assert more[name]["dr"] == more[name]["m2td3"] == 0  # "every DR and M2TD3 seed less"
        assert more[name]["rarl"] == 1  # "RARL's seeds split (1 of 5 more on each)"
    assert "every TD3 seed and 4 of NR-MDP's 5 score more" in text
    assert "(TD3 5 of 5, NR-MDP 4 of 5; DR and M2TD3 none). RARL's seeds split (1 of 5" in text


def test_the_hopper_reading_of_the_own_adversary_scores():
    import json

    text = flat(RESULTS / "hopper" / "README.md")
    published = json.loads((ROOT / "rrls/report/paper_results.json").read_text())
    paper = published["dynamic"]
    scores: dict[str, list[float]] = {}
    for algo in ("rarl", "nrmdp"):
        for run in sorted((RESULTS / "hopper" / "runs").glob(f"{algo}-*")):
            dynamic = pd.read_csv(run / "dynamic.csv")["return"]
            assert len(dynamic) == 10  # "10 episodes each"
            scores.setdefault(algo, []).append(dynamic.mean())
    average = {
        a: v["average_case"] for a, v in results_page.per_seed_so_far(RESULTS / "hopper").items()
    }
    for algo, name in (("nrmdp", "NR-MDP scores"), ("rarl", "RARL")):
        low, high = (spaced(v) for v in (min(scores[algo]), max(scores[algo])))
        mean, std = (spaced(v) for v in paper[algo]["hopper"])
        assert f"{name} {low} to {high}" in text and f"(the paper: {mean} ± {std}" in text
    assert all(s < a for s, a in zip(scores["rarl"], average["rarl"]))  # "on every seed"
    # beside the paper's numbers: this grid's budget, physics and seeds, and the paper's
    steps = json.loads((RESULTS / "hopper" / "benchmark.json").read_text())["steps"]
    seeds = {len(v) for v in scores.values()}
    assert len(seeds) == 1 and (published["steps"], published["seeds"]) == (5_000_000, 10)
    said = f"{seeds.pop()} seeds each"
    assert (
        f"here {steps // 1000} k steps on rrls's v5 physics, {said}" in text
        and "at 5 M steps over 10 seeds on the original's physics" in text
    )


def test_the_hopper_reading_of_what_survives_the_correction():
    """From the shipped runs' values through the report's own pairwise test."""
    from rrls.report.pairwise import pairwise

    folder = RESULTS / "hopper"
    text = flat(folder / "README.md")
    data = results_page.per_seed_so_far(folder)
    algos = ("td3", "dr", "m2td3", "rarl", "nrmdp")
    closest = {}
    for metric in ("worst_case", "average_case"):
        rows = pairwise({a: data[a][metric] for a in algos})
        assert all(r["p_holm"] >= 0.05 for r in rows)  # "nothing"
        closest[metric] = min(rows, key=lambda r: r["p_holm"])
    worst, average = closest["worst_case"], closest["average_case"]
    assert (worst["a"], worst["b"], worst["diff"] < 0) == ("td3", "m2td3", True)
    assert f"(Welch p = {worst['p']:.3f} on its own, {worst['p_holm']:.3f} after Holm's" in text
    above, below = (average["a"], average["b"])[:: 1 if average["diff"] > 0 else -1]
    assert (
        f"{display_name(above)} above {display_name(below)} ({average['p']:.3f} on its own, "
        f"{average['p_holm']:.3f} corrected)" in text
    )
    # the disjoint-interval line (generated from the same values) reproduces that pair
    disjoint = "**average case**, by disjoint 95 % intervals: reproduced (1): "
    said = f"{display_name(above)} above {display_name(below)}"
    reproduced = f"{disjoint}{display_name(above)} > {display_name(below)};" in text
    assert reproduced == ("corrected), whose 95 % intervals are disjoint" in text), said
    low, high = (spaced(-x) for x in reversed(worst["ci95"]))
    ahead = spaced(-worst["diff"])
    assert f"M2TD3 ahead of TD3 by {ahead} (95 % Welch interval [{low}, {high}])" in text
