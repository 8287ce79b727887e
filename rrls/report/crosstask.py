"""``rrls report DIR DIR ... --out OUT``: one report over several benchmarks, the paper's
cross-task Tables 4-5 (normalised worst and average case per task and their mean); written by
``rrls.report.writer.make_cross_report``.

References are trained a task at a time (each its own budget, seeds and episodes), so the
cross-task tables join benchmarks rather than asking for one that holds every task. The stores
are joined as they are: each task comes from exactly one benchmark and is normalised by that
benchmark's own TD3 and M2TD3 means, so the per-task cells are those of the task's own report.
What the tasks must share is what makes their normalised scores the same statistic: the
uncertainty set's name, the mesh, the physics, the simulator the runs trained on (a
twin-trained reference is never mixed with a CPU-trained one), and the protocol's disruptors,
schedule and episode limit. What may differ (the training
budget, the seeds, the episodes per point) is stated per task in the report, its captions and
``summary.json`` (``benchmark.by_task``).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from rrls.benchmark import benchfile
from rrls.benchmark.store import TABLES, load_store
from rrls.report.names import sort_algos, task_name

__all__ = ["PER_TASK", "SHARED", "joined", "sources_lines"]

#: the protocol fields every joined benchmark must share (the normalised score's meaning)
SHARED = (
    "uncertainty",
    "mesh",
    "endpoint",
    "physics",
    "simulator",
    "split",
    "observe",
    "disruptors",
    "schedule",
    "max_episode_steps",
)
#: the fields that may differ between tasks, stated per task
PER_TASK = ("steps", "seeds", "episodes", "dynamic_episodes", "eval_seed", "preset")


def joined(dirs: list[str | Path]) -> tuple[dict[str, Any], dict[str, Any]]:
    """The stores of ``dirs`` joined and one spec describing them (``by_task``: each task's
    source folder and per-task fields; a per-task field shared by all keeps its value, else
    ``None``). ``ValueError`` in one line when a folder is not a benchmark with finished runs,
    a task comes from two folders, or the shared protocol fields differ."""
    import pandas as pd

    if len(dirs) < 2:
        raise ValueError("a cross-task report joins two or more benchmark directories")
    specs, stores = [], []
    for d in dirs:
        if not benchfile.spec_path(d).exists():
            raise ValueError(f"{d} holds no benchmark.json: not a `rrls benchmark --out` directory")
        specs.append(benchfile.read_spec_json(d))
        stores.append(load_store(d))
    owner: dict[str, str] = {}
    for d, store in zip(dirs, stores):
        ev = store["evaluations"]
        if not len(ev):
            raise ValueError(f"{d}: no finished run to report")
        for task in dict.fromkeys(ev["task"]):
            if task in owner:
                raise ValueError(
                    f"task {task!r} is in both {owner[task]} and {d}: each task must come "
                    "from one benchmark"
                )
            owner[str(task)] = str(d)
    for field in SHARED:
        values = {str(d): s.get(field) for d, s in zip(dirs, specs)}
        if len({repr(v) for v in values.values()}) > 1:
            shown = ", ".join(f"{d}: {v!r}" for d, v in values.items())
            raise ValueError(
                f"the benchmarks differ in {field} ({shown}): their normalised scores are not "
                f"the same statistic; join benchmarks sharing {', '.join(SHARED)}"
            )
    by_task: dict[str, dict[str, Any]] = {}
    for d, spec, store in zip(dirs, specs, stores):
        for task in dict.fromkeys(store["evaluations"]["task"]):
            by_task[str(task)] = {"source": str(d), **{f: spec.get(f) for f in PER_TASK}}
    tables = {
        name: pd.concat([s[name] for s in stores if len(s[name])], ignore_index=True)
        if any(len(s[name]) for s in stores)
        else stores[0][name]
        for name in TABLES
    }
    combined: dict[str, Any] = {**specs[0]}
    for field in PER_TASK:
        values = [t[field] for t in by_task.values()]
        combined[field] = values[0] if all(v == values[0] for v in values) else None
    combined["tasks"] = list(by_task)
    combined["algos"] = sort_algos({a for s in specs for a in s.get("algos") or []})
    combined["seeds"] = sorted({int(x) for s in specs for x in s.get("seeds") or []})
    combined["by_task"] = by_task
    return tables, combined


def sources_lines(spec: dict[str, Any]) -> list[str]:
    """The report's section naming each task's benchmark and what differs between tasks."""
    by_task = spec.get("by_task") or {}
    if not by_task:
        return []
    lines = [
        "## Sources (one benchmark per task)",
        "",
        "Each task's runs, normalisation (its own TD3 and M2TD3) and per-task statistics come "
        "from its own benchmark; the Average column and the aggregates join them. Shared by "
        "all: "
        + ", ".join(f"{f} `{spec.get(f)}`" for f in SHARED if spec.get(f) is not None)
        + ".",
        "",
        "| task | benchmark | preset | training steps per run | seeds | episodes per point |",
        "|---|---|---|---|---|---|",
    ]
    for task, t in by_task.items():
        steps = f"{t['steps']:,}" if t.get("steps") else "not stated"
        lines.append(
            f"| {task_name(task)} | `{t['source']}` | {t.get('preset') or '–'} | {steps} | "
            f"{len(t.get('seeds') or [])} | {t.get('episodes')} |"
        )
    differ = [f for f in PER_TASK if f != "preset" and spec.get(f) is None]
    if differ:
        lines += [
            "",
            f"The tasks differ in {', '.join(differ)}: a task's cells are comparable within "
            "its column; the Average column averages tasks measured under these differences.",
        ]
    return [*lines, ""]
