"""A results page's record of its runs, from the runs' own files: one line per run (the commit
and the CPU kinds that trained it, its cost, its scores) and the summed cost with the machines.
``benchmarks/results_page.py`` writes them as the ``runs`` and ``compute`` blocks."""

from __future__ import annotations

import json
from collections.abc import Iterable
from pathlib import Path

from collect_runs import run_seconds  # benchmarks/, beside this script

from rrls import rundir
from rrls.algorithms import display_name, sort_algos


def changes(values: Iterable[str]) -> list[str]:
    """``values`` with each repeat of the one before dropped: a run's CPU kinds in the order
    its executions ran on them."""
    out: list[str] = []
    for value in values:
        if not out or out[-1] != value:
            out.append(value)
    return out


def machine_kind(machine: dict | None) -> str:
    """A machine as the pages name it: ``2-core AMD EPYC (X86_V3)``; unknown: ``unknown CPU``."""
    if not machine:
        return "unknown CPU"
    cores, cpu, simd = (machine.get(k, "?") for k in ("cores", "cpu", "simd"))
    return f"{cores}-core {cpu} ({simd})"


def runs(folder: Path) -> str:
    """One line per run: the rrls commit that trained it, its CPU kind, its cost (every execution
    where known: ``compute``) and its scores."""
    lines = [
        "| run | commit | CPU | executions | seconds | worst case | average case | own adversary |",
        "|---|---|---|---|---|---|---|---|",
    ]
    rows = []
    for result in folder.glob("runs/*/result.json"):
        info = json.loads(result.read_text())
        run = json.loads((result.parent / "run.json").read_text())
        provenance = run.get("provenance", {})
        simd = " → ".join(
            changes((e.get("machine") or {}).get("simd") or "?" for e in rundir.executions(run))
        )
        sha = provenance.get("commit") or "?"  # "+dirty": built from uncommitted changes
        commit = f"`{sha[:7]}{'+dirty' if sha.endswith('+dirty') else ''}`"
        rows.append((info, commit, simd, *run_seconds(result.parent)))
    order = {a: i for i, a in enumerate(sort_algos({r[0]["algorithm"] for r in rows}))}
    for info, commit, simd, seconds, executions in sorted(
        rows, key=lambda r: (r[0]["seed"], order[r[0]["algorithm"]])
    ):
        dyn = f"{info['dynamic_mean']:.1f}" if "dynamic_mean" in info else ""
        lines.append(
            f"| {display_name(info['algorithm'])} seed {info['seed']} | {commit} | {simd} | "
            f"{executions or '?'} | {seconds:.0f} | {info['worst_case']:.1f} | "
            f"{info['average_case']:.1f} | {dyn} |"
        )
    return "\n".join(lines) + "\n"


def compute(folder: Path) -> str:
    """The runs' own record of their cost (``collect_runs.run_seconds``: every execution of a
    resumed run where ``executions.csv`` lists them, else ``result.json``'s last execution) and
    the CPU kinds in ``run.json``."""
    seconds, kinds, known, resumed, runs = 0.0, {}, 0, 0, 0
    for path in folder.glob("runs/*/result.json"):
        spent, executions = run_seconds(path.parent)
        seconds, runs = seconds + spent, runs + 1
        known += executions > 0
        resumed += executions > 1
        run = json.loads((path.parent / "run.json").read_text())
        kind = " then ".join(
            changes(machine_kind(e.get("machine")) for e in rundir.executions(run))
        )
        kinds[kind] = kinds.get(kind, 0) + 1
    where = ", ".join(f"{k}: {n} runs" for k, n in sorted(kinds.items()))
    if known == runs:
        counted = (
            f"every execution counted: {resumed} of the {runs} runs were resumed after their "
            "process was stopped, and their earlier executions are timed from their TensorBoard "
            "files (`executions.csv`, to within a minute each)"
        )
    else:
        counted = (
            f"{runs - known} of the {runs} runs timed by `result.json` alone, which counts a "
            "resumed run's last execution only"
        )
    return (
        f"{seconds / 3600:.1f} hours of run time summed over the runs (each single-threaded: at "
        f"most that many CPU-hours; {counted}); {where or 'no run yet'}.\n"
    )
