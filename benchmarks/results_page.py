"""The numbers of a results page (``docs/results/<name>/README.md``), generated from its data.

    python3 benchmarks/results_page.py docs/results/hopper-200k --reference hopper-200k --write
    python3 benchmarks/results_page.py docs/results/hopper-200k --reference hopper-200k --check

A page holds blocks between ``<!-- generated:NAME -->`` and ``<!-- /generated -->``; this script
rewrites each from the shipped data: the report's per-run table (``tables/per_run.csv``: each
seed's worst and average case and final nominal return), the reference file's per-seed values
against the runs' own adversaries (checked equal to the per-run table on the other criteria)
and, where the folder has ``runs/``, each run's ``result.json``.
``--check`` (what ``tests/test_results_pages.py`` runs) fails when a block differs from what the
data give, so no number on a page is typed by hand. Blocks:

- ``summary``: per algorithm, the mean over seeds with its 95 % Student-t interval (the report's
  method, ``rrls.report.stats.t_interval``), each seed's final nominal return;
- ``orderings``: every pair of algorithms whose intervals do not overlap, per criterion, and the
  lowest and highest mean: the only orderings a page may state;
- ``runs``: one row per shipped run;
- ``earlier``: the algorithms retrained after a change of defaults, their earlier runs
  (sub-folder ``earlier/``, its own report) beside today's, seed for seed (RARL and NR-MDP also
  against their own final adversary);
- ``ablation``: NR-MDP and M2TD3 with their authors' details beside the runs of the same seeds
  (``ablation.csv``, written by ``benchmarks/ablation.py``).
"""

from __future__ import annotations

import argparse
import csv
import json
import re
import sys
from pathlib import Path
from typing import Any

from page_checks import seed_cell  # beside this script too
from page_runs import compute, runs

from rrls.algorithms import display_name, sort_algos
from rrls.report.pairwise import judge_paper, pairwise
from rrls.report.reference import load_reference
from rrls.report.stats import t_interval

METRICS = {"worst_case": "worst case", "average_case": "average case"}
#: per task: the nominal return TD3 must reach on every probed seed at the preset's budget
#: (HalfCheetah: the rule its budget was chosen by; Hopper: 2 500, the longer reference's rule)
TD3_RULE = {"halfcheetah": 4_000.0, "hopper": 2_500.0}
#: a block; ``SUB/NAME`` is the block NAME of the report in the page's folder SUB (no reference)
BLOCK = re.compile(r"(<!-- generated:([\w/-]+) -->\n)(.*?)(<!-- /generated -->)", re.S)


def per_seed(folder: Path) -> dict[str, dict[str, list[float]]]:
    """``{algo: {worst_case, average_case, nominal: values by seed}}`` from the report's
    ``tables/per_run.csv``."""
    out: dict[str, dict[int, dict[str, float]]] = {}
    with open(folder / "tables" / "per_run.csv", newline="") as f:
        for row in csv.DictReader(f):
            out.setdefault(row["algorithm"], {})[int(row["seed"])] = {
                "worst_case": float(row["worst_case"]),
                "average_case": float(row["average_case"]),
                "nominal": float(row["final_nominal_return"]),
            }
    return _by_seed(out, ("worst_case", "average_case", "nominal"))


def per_seed_so_far(folder: Path) -> dict[str, dict[str, list[float]]]:
    """``{algo: {worst_case, average_case: values by seed}}`` of a grid in progress, read from
    its finished runs' ``result.json`` (its report comes when the grid is complete)."""
    out: dict[str, dict[int, dict[str, Any]]] = {}
    for path in folder.glob("runs/*/result.json"):
        result = json.loads(path.read_text())
        out.setdefault(result["algorithm"], {})[int(result["seed"])] = result
    return _by_seed(out, tuple(METRICS))


def _by_seed(rows: dict[str, dict[int, dict[str, Any]]], keys: tuple[str, ...]) -> dict:
    """``{algo: {seed: row}}`` as ``{algo: {key: values in seed order}}``."""
    return {
        algo: {k: [float(seeds[s][k]) for s in sorted(seeds)] for k in keys}
        for algo, seeds in rows.items()
    }


def dynamic(folder: Path, reference: str | None) -> dict[str, str]:
    """``{algo: cell}`` of the runs against their own adversaries: the reference's per-seed
    values where it has them (checked against the folder's per-run table), else the report's
    mean ± std."""
    cells: dict[str, str] = {}
    if reference is not None:
        data = per_seed(folder)
        for row in load_reference(reference).rows:
            values = list(row["values"] or [])
            if row["metric"] == "dynamic":
                cells[row["algorithm"]] = seed_cell(values)
            elif values != data[row["algorithm"]][row["metric"]]:
                raise SystemExit(
                    f"{reference}: {row['algorithm']} {row['metric']} per seed "
                    f"differs from {folder}/tables/per_run.csv"
                )
        return cells
    path = folder / "tables" / "dynamic.csv"
    if path.exists():
        with open(path, newline="") as f:
            for row in csv.DictReader(f):
                if not row["mean"]:  # no run of it yet
                    continue
                mean, n = float(row["mean"]), int(row.get("n_seeds") or 0)
                if n < 2:  # one seed: its value alone (a std of one value says nothing)
                    cells[row["algorithm"]] = f"{mean:.1f}"
                else:
                    cells[row["algorithm"]] = f"{mean:.1f} ± {float(row['std']):.1f} (std)"
    return cells


def summary(data: dict[str, dict[str, list[float]]], dyn: dict[str, str]) -> str:
    lines = [
        "| algorithm | seeds | worst case | average case | final nominal return per seed "
        "| vs own adversary |",
        "|---|---|---|---|---|---|",
    ]
    for algo in sort_algos(data):
        cells = data[algo]
        nom = ", ".join(f"{v:.0f}" for v in cells["nominal"])
        lines.append(
            f"| {display_name(algo)} | {len(cells['worst_case'])} | "
            f"{seed_cell(cells['worst_case'])} | {seed_cell(cells['average_case'])} | {nom} | "
            f"{dyn.get(algo, '')} |"
        )
    return "\n".join(lines) + "\n"


def orderings(data: dict[str, dict[str, list[float]]]) -> str:
    lines = []
    for metric, words in METRICS.items():
        stats = {}
        for algo in sort_algos(data):
            values = data[algo].get(metric, [])
            if len(values) >= 2:
                stats[algo] = (sum(values) / len(values), t_interval(values))
        if not stats:
            continue
        single = [display_name(a) for a in sort_algos(data) if a not in stats]
        unranked = f" (one seed, not ranked: {', '.join(single)})" if single else ""
        if len(stats) == 1:
            only = display_name(next(iter(stats)))
            lines.append(
                f"- **{words}**: only {only} has two seeds or more: no ordering yet{unranked}."
            )
            continue
        pairs = [
            f"{display_name(a)} above {display_name(b)}"
            for a in stats
            for b in stats
            if a != b and stats[a][1][0] > stats[b][1][1]
        ]
        low = min(stats, key=lambda a: stats[a][0])
        high = max(stats, key=lambda a: stats[a][0])
        resolved = "; ".join(pairs) if pairs else "none (every pair of intervals overlaps)"
        lines.append(
            f"- **{words}**: lowest mean {display_name(low)} ({stats[low][0]:.1f}), highest "
            f"{display_name(high)} ({stats[high][0]:.1f}); non-overlapping 95 % intervals: "
            f"{resolved}{unranked}."
        )
    return "\n".join(lines) + "\n"


def uncertainty_set(folder: Path) -> str:
    """The benchmark's set per task: each parameter's bounds and the model's nominal value,
    inside the set or not (the task's XML as compiled, what an unperturbed env runs)."""
    from rrls.benchmark.benchfile import read_spec_json
    from rrls.envs import ROBUST_ENVS, get_uncertainty_set

    spec = read_spec_json(folder)  # the protocol's fields flat, whatever the file's format
    lines = [
        "| task | parameter | set | model's nominal value | in the set |",
        "|---|---|---|---|---|",
    ]
    for task in spec["tasks"]:
        box = get_uncertainty_set(task, spec["uncertainty"])
        nominal = ROBUST_ENVS[task]().get_params()
        for name, lo, hi in zip(box.names, box.low, box.high):
            value = nominal[name]
            inside = "yes" if lo <= value <= hi else "no"
            lines.append(f"| {task} | {name} | [{lo:g}, {hi:g}] | {value:.3f} | {inside} |")
    return "\n".join(lines) + "\n"


def evaluation(folder: Path) -> str:
    """How the shipped runs were evaluated (their ``eval/summary.json``): the mesh, whether it
    reaches the upper bounds, episodes per point; and how many worst points lie on an upper
    bound (slices the paper's ``np.arange`` mesh does not have)."""
    kinds, on_edge, n = set(), 0, 0
    for path in sorted(folder.glob("runs/*/eval/summary.json")):
        info = json.loads(path.read_text())
        box = info["uncertainty"]
        kinds.add((info["mesh"], bool(info["endpoint"]), info["episodes"]))
        worst = [info["worst_point"][name] for name in box["names"]]
        on_edge += any(abs(w - hi) <= 1e-9 * max(1.0, abs(hi)) for w, hi in zip(worst, box["high"]))
        n += 1
    lines = []
    for mesh, endpoint, episodes in sorted(kinds):
        how = (
            "`np.linspace`, both bounds included (rrls's default mesh, not the paper's)"
            if endpoint
            else "`np.arange` from the lower bound, the upper bound excluded (the paper's mesh)"
        )
        lines.append(
            f"- {mesh} points per dimension ({mesh ** len(box['names']):,} points), {how}, "
            f"{episodes} episodes per point."
        )
    if any(endpoint for _, endpoint, _ in kinds):
        lines.append(
            f"- {on_edge} of {n} runs have their worst point on an upper bound of the set, a "
            "slice the paper's mesh does not have."
        )
    return "\n".join(lines) + "\n"


def paper_comparison(folder: Path) -> str:
    """This folder's runs (those finished so far, while its grid is in progress) beside the
    paper's Table 7 / 8 row of the same task (raw worst and average case, mean ± std over the
    paper's 10 seeds), and for every pair of algorithms the paper orders: reproduced (this
    benchmark's 95 % intervals disjoint, the same way), contradicted (disjoint, the other way)
    or unresolved (they overlap)."""
    from rrls.report.writer import paper_results

    paper = paper_results()
    spec = json.loads((folder / "benchmark.json").read_text())
    (task,) = spec["tasks"]
    complete = (folder / "tables" / "per_run.csv").is_file()
    data = per_seed(folder) if complete else per_seed_so_far(folder)
    lines = [
        "| algorithm | worst case, here | worst case, paper | average case, here | average "
        "case, paper |",
        "|---|---|---|---|---|",
    ]
    tables = {"worst_case": "raw_worst_case", "average_case": "raw_average_case"}
    for algo in sort_algos(data):
        cells = []
        for metric, table in tables.items():
            mean, std = paper[table][algo][task]
            cells += [seed_cell(data[algo][metric]), f"{mean:.1f} ± {std:.1f}"]
        lines.append(f"| {display_name(algo)} | " + " | ".join(cells) + " |")
    lines.append("")
    few = [a for a in sort_algos(data) if len(data[a]["worst_case"]) < 2]
    for metric, table in tables.items():
        verdicts: dict[str, list[str]] = {"reproduced": [], "contradicted": [], "unresolved": []}
        algos = [a for a in sort_algos(data) if a not in few]  # an interval needs two seeds
        ci = {a: t_interval(data[a][metric]) for a in algos}
        for i, a in enumerate(algos):
            for b in algos[i + 1 :]:
                hi, lo = (a, b) if paper[table][a][task][0] > paper[table][b][task][0] else (b, a)
                pair = f"{display_name(hi)} > {display_name(lo)}"
                if ci[hi][0] > ci[lo][1]:
                    verdicts["reproduced"].append(pair)
                elif ci[lo][0] > ci[hi][1]:
                    verdicts["contradicted"].append(pair)
                else:
                    verdicts["unresolved"].append(pair)
        text = "; ".join(
            f"{k} ({len(v)}): {', '.join(v) if v else 'none'}" for k, v in verdicts.items()
        )
        lines.append(f"- **{METRICS[metric]}**, by disjoint 95 % intervals: {text}.")
        lines.append(
            f"- **{METRICS[metric]}**, by Welch's test, Holm-corrected: "
            + _holm({a: data[a][metric] for a in algos}, paper, task, metric)
        )
    if few:
        names = ", ".join(display_name(a) for a in few)
        lines.append(f"- not judged yet (fewer than two seeds, no interval): {names}.")
    return "\n".join(lines) + "\n"


def _p(p: float) -> str:
    return "< 0.001" if p < 0.001 else f"= {p:.3f}"


def _holm(values: dict[str, list[float]], paper: dict, task: str, metric: str) -> str:
    """The paper's orderings judged by Welch's test with Holm's correction over the pairs
    (``rrls.report.pairwise``, the report's method), the uncorrected p beside each."""
    rows = pairwise(values)
    verdicts: dict[str, list[str]] = {"reproduced": [], "contradicted": [], "unresolved": []}
    for j in judge_paper(rows, paper, task, metric):
        r = j["row"]
        mark = (
            "; the paper: not significant"
            if j["paper_says_not_significant"]
            else ("" if j["paper_resolved"] else "; not resolved by the paper's own numbers")
        )
        p = f"p {_p(r['p'])}, Holm {_p(r['p_holm'])}" if r["p"] is not None else "no test"
        if r["diff"] is not None and (r["diff"] > 0) != (r["a"] == j["hi"]):
            p = f"here the other way, {p}"
        verdicts[j["verdict"]].append(
            f"{display_name(j['hi'])} > {display_name(j['lo'])} ({p}{mark})"
        )
    return (
        "; ".join(f"{k} ({len(v)}): {', '.join(v) if v else 'none'}" for k, v in verdicts.items())
        + "."
    )


def status(folder: Path) -> str:
    """How much of the benchmark's grid the folder holds (a reference produced in pieces)."""
    spec = json.loads((folder / "benchmark.json").read_text())
    done: dict[str, list[int]] = {}
    for path in folder.glob("runs/*/result.json"):
        info = json.loads(path.read_text())
        done.setdefault(info["algorithm"], []).append(int(info["seed"]))
    total = len(spec["algos"]) * len(spec["tasks"]) * len(spec["seeds"])
    n = sum(len(v) for v in done.values())
    parts = [
        f"{display_name(a)} seed{'s' if len(done[a]) > 1 else ''} "
        f"{', '.join(map(str, sorted(done[a])))}"
        for a in sort_algos(done)
    ]
    missing = [display_name(a) for a in sort_algos(spec["algos"]) if a not in done]
    if not n:
        return f"**0 of {total} runs finished** yet.\n"
    return (
        f"**{n} of {total} runs finished** ({'; '.join(parts) or 'none'})"
        + (f"; none finished yet: {', '.join(missing)}" if missing else "")
        + ".\n"
    )


def td3_budget(folder: Path, threshold: float = 4_000.0) -> str:
    """TD3's nominal return per seed at every 50 000 steps and where it first reaches
    ``threshold``: how the preset's budget was chosen (the TD3 runs measured first); then which
    seeds are at or above it at the budget itself, the rule's own test (a seed can reach the
    threshold and fall back below it)."""
    rows = {}
    for path in sorted(folder.glob("runs/td3-*/scalars.csv")):
        seed = int(path.parent.name.rpartition("seed")[2])
        with open(path, newline="") as f:
            rows[seed] = {
                int(r["step"]): float(r["value"])
                for r in csv.DictReader(f)
                if r["metric"] == "eval/nominal_return"
            }
    if not rows:
        return "(no TD3 run yet)\n"
    steps = sorted({s for r in rows.values() for s in r if s % 50_000 == 0})
    lines = [
        "| seed | "
        + " | ".join(f"{s // 1000} k" for s in steps)
        + f" | first ≥ {threshold:,.0f} |",
        "|---" * (len(steps) + 2) + "|",
    ]
    for seed, by_step in sorted(rows.items()):
        first = next((s for s in sorted(by_step) if by_step[s] >= threshold), None)
        cells = [f"{by_step[s]:.0f}" if s in by_step else "" for s in steps]
        reach = f"{first // 1000} k" if first is not None else "not reached"
        lines.append(f"| {seed} | " + " | ".join(cells) + f" | {reach} |")
    budget = int(json.loads((folder / "benchmark.json").read_text())["steps"])
    final = {seed: by_step[budget] for seed, by_step in rows.items() if budget in by_step}
    below = [f"seed {s} ({v:,.0f})" for s, v in sorted(final.items()) if v < threshold]
    held = len(final) - len(below)
    lines += [
        "",
        f"At the budget ({budget // 1000} k steps), {held} of {len(final)} seed"
        + ("s" if len(final) != 1 else "")
        + (" is" if held == 1 else " are")
        + f" at or above {threshold:,.0f}"
        + (f"; below it: {', '.join(below)}." if below else "."),
    ]
    return "\n".join(lines) + "\n"


def own_adversary(folder: Path) -> dict[str, list[float]]:
    """``{algo: values by seed}`` of the runs against their own final adversary (``result.json``'s
    ``dynamic_mean``), for the algorithms all of whose runs have one."""
    found: dict[str, dict[int, float | None]] = {}
    for result in folder.glob("runs/*/result.json"):
        info = json.loads(result.read_text())
        found.setdefault(info["algorithm"], {})[int(info["seed"])] = info.get("dynamic_mean")
    return {
        algo: [by_seed[s] for s in sorted(by_seed)]
        for algo, by_seed in found.items()
        if all(v is not None for v in by_seed.values())
    }


def earlier(folder: Path, sub: str = "earlier") -> str:
    """Per algorithm of ``folder/sub`` (the same seeds trained under earlier defaults) and metric:
    the earlier runs and today's, mean with its 95 % t interval, their ratio, each seed's
    difference, and whether the intervals separate (the only change a page may state)."""
    before, now = per_seed(folder / sub), per_seed(folder)
    for seeds, where in ((before, folder / sub), (now, folder)):
        for algo, values in own_adversary(where).items():  # the two-player games' own metric
            if algo in seeds:
                seeds[algo]["dynamic"] = values
    lines = [
        "| algorithm | metric | earlier defaults | today's defaults | today / earlier "
        "| per seed (today - earlier) | intervals |",
        "|---|---|---|---|---|---|---|",
    ]
    words = {**METRICS, "nominal": "final nominal return", "dynamic": "vs own adversary"}
    for algo in sort_algos(before):
        if algo not in now:
            continue
        for metric, name in words.items():
            if metric not in before[algo] or metric not in now[algo]:
                continue
            a, b = before[algo][metric], now[algo][metric]
            if len(a) != len(b):  # per_seed lists seeds in order: only equal sets pair
                raise SystemExit(f"{folder}: {algo} has {len(a)} earlier runs, {len(b)} today")
            ca, cb = t_interval(a), t_interval(b)
            apart = ca is not None and cb is not None and (cb[0] > ca[1] or ca[0] > cb[1])
            mean_a, mean_b = sum(a) / len(a), sum(b) / len(b)
            ratio = f"{mean_b / mean_a:.2f}" if mean_a else ""
            diffs = ", ".join(f"{y - x:+.0f}" for x, y in zip(a, b))
            lines.append(
                f"| {display_name(algo)} | {name} | {seed_cell(a)} | {seed_cell(b)} | {ratio} "
                f"| {diffs} "
                f"| {'apart' if apart else 'overlap'} |"
            )
    return "\n".join(lines) + "\n"


def blocks(folder: Path, reference: str | None) -> dict[str, str]:
    out = {}
    spec = folder / "benchmark.json"
    task = json.loads(spec.read_text())["tasks"][0] if spec.exists() else None
    if (folder / "tables" / "per_run.csv").is_file():  # a grid in progress has no report yet
        data = per_seed(folder)
        out = {"summary": summary(data, dynamic(folder, reference)), "orderings": orderings(data)}
    if (folder / "benchmark.json").exists():
        out["set"] = uncertainty_set(folder)
        out["status"] = status(folder)
        out["td3_budget"] = td3_budget(folder, TD3_RULE.get(task, 4_000.0))
        text = (folder / "README.md").read_text() if (folder / "README.md").exists() else ""
        if "<!-- generated:paper -->" in text:
            out["paper"] = paper_comparison(folder)
    if (folder / "runs").is_dir():
        out["runs"] = runs(folder)
        out["evaluation"] = evaluation(folder)
        out["compute"] = compute(folder)
    if (folder / "earlier" / "tables" / "per_run.csv").is_file():
        out["earlier"] = earlier(folder)
    if (folder / "cleanrl_td3_returns.csv").is_file():
        import td3_sanity  # beside this file

        steps = td3_sanity.TASKS[task][0]
        out["sanity"] = td3_sanity.table(folder, folder / "cleanrl_td3_returns.csv", steps)
    import page_checks  # beside this file

    for name in ("rechecked", "physics"):
        block = getattr(page_checks, name)(folder)
        if block is not None:
            out[name] = block
    if (folder / "runs").is_dir() and (folder / "benchmark.json").exists():
        out["differences"] = page_checks.differences(folder)
    if (folder / "ablation.csv").is_file():
        import ablation  # beside this file
        import pandas as pd

        out["ablation"] = ablation.table(pd.read_csv(folder / "ablation.csv")) + "\n"
    return out


def page_blocks(folder: Path, reference: str | None) -> dict[str, str]:
    """Every block the folder's page names: its own, and ``SUB/NAME`` of its sub-folders."""
    text = (folder / "README.md").read_text()
    generated = blocks(folder, reference)
    for sub in {n.rpartition("/")[0] for n in BLOCK_NAMES.findall(text) if "/" in n}:
        generated.update({f"{sub}/{k}": v for k, v in blocks(folder / sub, None).items()})
    return generated


BLOCK_NAMES = re.compile(r"<!-- generated:([\w/-]+) -->")


def update(page: Path, generated: dict[str, str]) -> tuple[str, list[str]]:
    """The page with its blocks regenerated, and the names of the blocks that changed."""
    text, changed = page.read_text(), []

    def fill(match: re.Match) -> str:
        name = match.group(2)
        if name not in generated:
            raise SystemExit(f"{page}: no data for the block {name!r}")
        if match.group(3) != generated[name]:
            changed.append(name)
        return match.group(1) + generated[name] + match.group(4)

    return BLOCK.sub(fill, text), changed


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("folder", type=Path)
    parser.add_argument("--reference", help="the folder's shipped reference (name or file)")
    what = parser.add_mutually_exclusive_group(required=True)
    what.add_argument("--write", action="store_true")
    what.add_argument("--check", action="store_true")
    args = parser.parse_args()
    page = args.folder / "README.md"
    text, changed = update(page, page_blocks(args.folder, args.reference))
    if args.write:
        page.write_text(text)
    elif changed:
        sys.exit(f"{page}: generated blocks out of date: {', '.join(changed)}")
