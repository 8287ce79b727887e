"""Copy a benchmark's finished runs' small files into a results folder, to commit as they land.

    python3 benchmarks/collect_runs.py /path/to/bench docs/results/hopper

A reference produced in pieces on machines that may not come back keeps what is committed: each
finished run (``result.json`` present) contributes its policy, ``run.json``, ``result.json``,
curves (``scalars.csv``) and evaluation (summary and episodes, dynamic episodes) — never
checkpoints, replay buffers or TensorBoard files. ``benchmark.json`` comes along, so
``rrls report DEST`` (after ``rrls benchmark`` would resume the rest) rebuilds the report.
"""

from __future__ import annotations

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
    return copied


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit("usage: collect_runs.py BENCH_DIR DEST_DIR")
    names = collect(Path(sys.argv[1]), Path(sys.argv[2]))
    print("\n".join(names) if names else "nothing new")
