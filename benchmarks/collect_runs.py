"""Copy a benchmark's finished runs' small files into a results folder, to commit as they land.

    python3 benchmarks/collect_runs.py /path/to/bench docs/results/hopper-200k

A reference produced in pieces on machines that may not come back keeps what is committed: each
finished run (``result.json`` present) contributes its policy, ``run.json``, ``result.json``,
curves (``scalars.csv``) and evaluation (summary and episodes, dynamic episodes) — never
checkpoints, replay buffers or TensorBoard files. ``benchmark.json`` comes along, so
``rrls report DEST`` (after ``rrls benchmark`` would resume the rest) rebuilds the report.

A run resumed after its process was stopped was trained in several executions, and its
``result.json`` times only the last (``seconds``: training since resuming, and evaluation). Each
execution wrote its own TensorBoard file, so ``executions.csv`` records them all: per file its
first and last event's wall time and steps, and ``in_result`` (1: the execution that
``result.json`` times). The earlier executions' spans plus ``seconds`` are the run's cost. A
file's first step is the first it logged, past its header (at step 0 whatever the step resumed
from; files written before this rule carry that 0); ``run.json``'s ``provenance.executions``
has the exact step each execution started from.
"""

from __future__ import annotations

import csv
import json
import shutil
import sys
from pathlib import Path

KEEP = (
    "policy.npz",
    "adversary.npz",
    "run.json",
    "result.json",
    "scalars.csv",
    "dynamic.csv",
    "eval/summary.json",
    "eval/evaluation.json",
    "eval/episodes.parquet",
    "eval/episodes.csv",
)


def collect(bench: Path, dest: Path) -> list[str]:
    """The names of the runs copied (finished runs not yet in ``dest``, or changed)."""
    copied = []
    dest.mkdir(parents=True, exist_ok=True)
    for name in ("benchmark.json", "benchmark.json.sha256"):
        if (bench / name).exists():
            shutil.copy2(bench / name, dest / name)
    for run in sorted((bench / "runs").glob("*/result.json")):
        src = run.parent
        out = dest / "runs" / src.name
        for rel in KEEP:
            for path in (src / rel, src / f"{rel}.sha256"):
                if path.is_file():
                    target = out / path.relative_to(src)
                    target.parent.mkdir(parents=True, exist_ok=True)
                    if not target.exists() or target.read_bytes() != path.read_bytes():
                        shutil.copy2(path, target)
                        if src.name not in copied:
                            copied.append(src.name)
        if executions(src, out / EXECUTIONS) and src.name not in copied:
            copied.append(src.name)
    return copied


EXECUTIONS = "executions.csv"
COLUMNS = ("started", "ended", "first_step", "last_step", "in_result")


def executions(run: Path, dest: Path) -> bool:
    """Write ``dest`` from ``run/tb``'s event files (one row per execution); ``False`` where the
    run has no TensorBoard files (kept as it was) or ``dest`` is already what they give."""
    files = sorted((run / "tb").glob("events.out.tfevents.*"))
    if not files:
        return False
    from tensorboard.backend.event_processing.event_file_loader import EventFileLoader

    result = run / "result.json"
    # the execution result.json times began `seconds` before it was written
    began = result.stat().st_mtime - float(json.loads(result.read_text())["seconds"])
    rows = []
    for path in files:
        # the file's header event is at step 0 whatever step the execution resumed from
        loaded = EventFileLoader(str(path)).Load()
        events = [(e.wall_time, e.step) for e in loaded if not e.HasField("file_version")]
        if not events:
            continue
        times, steps = [t for t, _ in events], [s for _, s in events]
        # a minute's slack: the event file opens just after the execution's clock starts
        rows.append((min(times), max(times), min(steps), max(steps), int(min(times) > began - 60)))
    if not any(row[4] for row in rows):  # it trained nothing (a checkpoint at the budget,
        # evaluated): no event file of its own; the span result.json times, at the final step
        step = int(json.loads((run / "run.json").read_text())["steps"])
        rows.append((began, result.stat().st_mtime, step, step, 1))
    rows.sort()
    lines = [",".join(COLUMNS)] + [f"{a:.3f},{b:.3f},{c},{d},{e}" for a, b, c, d, e in rows]
    text = "\n".join(lines) + "\n"
    if dest.exists() and dest.read_text() == text:
        return False
    dest.parent.mkdir(parents=True, exist_ok=True)
    tmp = dest.with_name(dest.name + ".tmp")  # atomic: a killed copy leaves the old file
    tmp.write_text(text)
    tmp.replace(dest)
    return True


def run_seconds(run: Path) -> tuple[float, int]:
    """A shipped run's cost in seconds and its number of executions: ``result.json``'s
    ``seconds`` plus the earlier executions' spans in ``executions.csv`` (without that file,
    ``seconds`` alone, and 0 executions: not known)."""
    seconds = float(json.loads((run / "result.json").read_text()).get("seconds") or 0.0)
    path = run / EXECUTIONS
    if not path.exists():
        return seconds, 0
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    earlier = [r for r in rows if r["in_result"] == "0"]
    return seconds + sum(float(r["ended"]) - float(r["started"]) for r in earlier), len(earlier) + 1


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit("usage: collect_runs.py BENCH_DIR DEST_DIR")
    names = collect(Path(sys.argv[1]), Path(sys.argv[2]))
    print("\n".join(names) if names else "nothing new")
