"""Two blocks of a results page that check the reference against its own noise and physics,
generated from shipped data (``benchmarks/results_page.py`` calls them):

- ``rechecked``: per algorithm, the paper's worst case beside the same runs' worst case
  rechecked with fresh episodes and the 5th percentile of their point means (each run's
  ``result.json``: ``rrls.evaluation.recheck``), and the orderings each statistic gives;
- ``physics``: per algorithm, the worst and average case on rrls's v5 physics beside the same
  policies evaluated on the paper's physics (``paper_physics.csv``, written by
  ``benchmarks/paper_physics.py``) with the per-run change and its paired interval, and
  whether the orderings change.
"""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np

from rrls import rundir
from rrls.algorithms import display_name, sort_algos
from rrls.benchmark import benchfile
from rrls.report.pairwise import pairwise
from rrls.report.stats import t_interval


def seed_cell(values: list[float]) -> str:
    """Per-seed values as a page shows them: the mean with its 95 % Student-t interval (the
    report's method, ``rrls.report.stats.t_interval``); one seed: its value."""
    if not values:
        return ""
    mean = sum(values) / len(values)
    ci = t_interval(values)
    return f"{mean:.1f}" if ci is None else f"{mean:.1f} [{ci[0]:.1f}, {ci[1]:.1f}]"


def ranked(values: dict[str, list[float]]) -> list[str]:
    """The algorithms by mean, highest first."""
    return sorted(values, key=lambda a: -float(np.mean(values[a])))


def resolved(values: dict[str, list[float]]) -> list[tuple[str, str]]:
    """The pairs ``(higher, lower)`` Welch + Holm resolves at 5 %."""
    return [
        (r["a"], r["b"]) if r["diff"] > 0 else (r["b"], r["a"])
        for r in pairwise(values)
        if r["p_holm"] is not None and r["p_holm"] < 0.05
    ]


def pairs_text(pairs: list[tuple[str, str]]) -> str:
    return ", ".join(f"{display_name(a)} > {display_name(b)}" for a, b in pairs) or "none"


def _order(values: dict[str, list[float]]) -> str:
    """The algorithms by mean, highest first, and the pairs Welch + Holm resolves."""
    text = " > ".join(display_name(a) for a in ranked(values))
    return f"by mean {text}; resolved (Welch, Holm-corrected): {pairs_text(resolved(values))}"


def moved(v5: dict[str, list[float]], paper: dict[str, list[float]]) -> str:
    """Whether the paper's physics changes an ordering: the order by mean, and the resolved
    pairs one physics has and the other lacks."""
    before, after = ranked(v5), ranked(paper)
    swapped = [
        f"{display_name(x)} and {display_name(y)}"
        for i, x in enumerate(before)
        for y in before[i + 1 :]
        if after.index(x) > after.index(y)
    ]
    text = f"by mean, {', '.join(swapped)} swap" if swapped else "the same order by mean"
    a, b = resolved(v5), resolved(paper)
    only_paper, only_v5 = [p for p in b if p not in a], [p for p in a if p not in b]
    flipped = [p for p in a if p[::-1] in b]
    if flipped:
        text += "; resolved the other way: " + pairs_text(flipped)
    if not only_paper and not only_v5:
        return text + "; the same resolved pairs" + ("" if a else " (none)")
    return (
        f"{text}; resolved on the paper's physics only: {pairs_text(only_paper)}; "
        f"on v5 only: {pairs_text(only_v5)}"
    )


def rechecked(folder: Path) -> str | None:
    """The ``rechecked`` block, or None while no run of the folder was rechecked."""
    rows: dict[str, dict[str, list[float]]] = {}
    quantiles = set()
    for path in sorted(folder.glob("runs/*/result.json")):
        result = json.loads(path.read_text())
        if "worst_case_rechecked" not in result:
            continue
        by = rows.setdefault(result["algorithm"], {"paper": [], "rechecked": [], "q": []})
        by["paper"].append(result["worst_case"])
        by["rechecked"].append(result["worst_case_rechecked"])
        by["q"].append(result["worst_case_q"])
        quantiles.add((result["recheck"]["worst"], result["recheck"]["episodes"]))
        quantiles.add(result["recheck"]["quantile"])
    if not rows:
        return None
    algos = sort_algos(rows)
    lines = [
        "| algorithm | runs | worst case (the paper's) | rechecked | rechecked − paper's, per "
        "seed | 5th percentile of the point means |",
        "|---|---|---|---|---|---|",
    ]
    for a in algos:
        by = rows[a]
        gain = ", ".join(f"{r - p:+.0f}" for p, r in zip(by["paper"], by["rechecked"]))
        lines.append(
            f"| {display_name(a)} | {len(by['paper'])} | {seed_cell(by['paper'])} | "
            f"{seed_cell(by['rechecked'])} | {gain} | {seed_cell(by['q'])} |"
        )
    lines.append("")
    for key, name in (("paper", "the paper's worst case"), ("rechecked", "rechecked")):
        lines.append(f"- **{name}**: " + _order({a: rows[a][key] for a in algos}) + ".")
    return "\n".join(lines) + "\n"


def read_physics(path: Path) -> dict[str, dict[str, list[float]]]:
    """``paper_physics.csv`` per algorithm: ``worst_case_v5``, ``worst_case_paper``,
    ``average_case_v5``, ``average_case_paper``, each a list over its runs in file order."""
    data: dict[str, dict[str, list[float]]] = {}
    with open(path, newline="") as f:
        for row in csv.DictReader(f):
            by = data.setdefault(row["algorithm"], {})
            for metric in ("worst_case", "average_case"):
                for physics in ("v5", "paper"):
                    key = f"{metric}_{physics}"
                    by.setdefault(key, []).append(float(row[key]))
    return data


def physics(folder: Path) -> str | None:
    """The ``physics`` block, or None without ``paper_physics.csv``."""
    path = folder / "paper_physics.csv"
    if not path.is_file():
        return None
    data = read_physics(path)
    algos = sort_algos(data)
    lines = [
        "| algorithm | runs | worst case, v5 | worst case, paper's physics | change (paired) | "
        "average case, v5 | average case, paper's physics | change (paired) |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for a in algos:
        by = data[a]
        cells = []
        for metric in ("worst_case", "average_case"):
            v5, paper = by[f"{metric}_v5"], by[f"{metric}_paper"]
            cells += [seed_cell(v5), seed_cell(paper), change_cell(v5, paper)]
        lines.append(
            f"| {display_name(a)} | {len(by['worst_case_v5'])} | " + " | ".join(cells) + " |"
        )
    lines.append("")
    for metric, name in (("worst_case", "worst case"), ("average_case", "average case")):
        for physics_name, key in (("v5", "v5"), ("the paper's physics", "paper")):
            order = _order({a: data[a][f"{metric}_{key}"] for a in algos})
            lines.append(f"- **{name}, {physics_name}**: {order}.")
    for metric, name in (("worst_case", "worst case"), ("average_case", "average case")):
        v5 = {a: data[a][f"{metric}_v5"] for a in algos}
        paper = {a: data[a][f"{metric}_paper"] for a in algos}
        lines.append(f"- **{name}, v5 → the paper's physics**: {moved(v5, paper)}.")
    return "\n".join(lines) + "\n"


def change_cell(before: list[float], after: list[float]) -> str:
    """The mean per-run change ``after − before`` with its paired 95 % Student-t interval (the
    same policies on two physics: each run is its own control)."""
    diffs = [b - a for a, b in zip(before, after)]
    mean = sum(diffs) / len(diffs)
    ci = t_interval(diffs)
    return f"{mean:+.1f}" if ci is None else f"{mean:+.1f} [{ci[0]:+.1f}, {ci[1]:+.1f}]"


#: what the RRLS authors' code ran on at the paper's time (SuReLI/RRLS 428665c, 2024-06-06:
#: ``gymnasium==1.0.0a1``, which pins ``mujoco==2.3.3``)
ORIGINAL = {"gymnasium": "1.0.0a1", "mujoco": "2.3.3"}


def differences(folder: Path) -> str:
    """The ``differences`` block: what this reference holds against the paper's protocol, read
    from the benchmark, its runs and the paper's published settings."""
    from rrls.report.writer import paper_results

    paper = paper_results()
    spec = json.loads((folder / "benchmark.json").read_text())
    versions: dict[str, set[str]] = {}
    m2td3_warmup = set()
    for path in sorted(folder.glob("runs/*/run.json")):
        run = rundir.read_run_json(path.parent)  # any run.json format
        for k in ("gymnasium", "mujoco"):
            versions.setdefault(k, set()).add(run["versions"][k])
        if run["algorithm"] == "m2td3":
            m2td3_warmup.add(int(run["config"]["hyper"]["learning_starts"]))
    if not m2td3_warmup and "m2td3" in spec["algos"]:  # a grid before its first M2TD3 run
        m2td3_warmup.add(benchfile.read_spec(folder).warmup("m2td3"))
    steps, seeds = int(spec["steps"]), len(spec["seeds"])
    rows = [
        (
            "budget",
            f"{steps:,} steps per run",
            f"{paper['steps']:,}",
            f"{steps / paper['steps']:.0%}",
        ),
        ("seeds", f"{seeds}", f"{paper['seeds']}", f"{seeds / paper['seeds']:.0%}"),
        (
            "physics",
            "rrls v5: Gymnasium v5 models, derived constants recomputed after every mass write "
            "(`mj_setConst`)",
            "the original code's writes on the v5 models, constants not recomputed",
            "measured below" if (folder / "paper_physics.csv").is_file() else "not measured yet",
        ),
    ]
    for k in ("mujoco", "gymnasium"):
        rows.append((k, ", ".join(sorted(versions.get(k, {"?"}))), ORIGINAL[k], ""))
    for w in sorted(m2td3_warmup):
        learn = max(steps - w, 0)
        paper_learn = paper["steps"] - w
        rows.append(
            (
                "M2TD3's learning steps",
                f"{learn:,} of {steps:,} ({learn / steps:.0%}; {w:,} random warm-up)",
                f"{paper_learn:,} of {paper['steps']:,} ({paper_learn / paper['steps']:.0%})",
                "",
            )
        )
    lines = ["| | this reference | the paper | here / paper |", "|---|---|---|---|"]
    lines += [f"| {a} | {b} | {c} | {d} |" for a, b, c, d in rows]
    return "\n".join(lines) + "\n"
