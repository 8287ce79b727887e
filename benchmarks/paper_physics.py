"""Every shipped policy of a results folder re-evaluated on the paper's physics (evaluation only).

    python3 benchmarks/paper_physics.py docs/results/halfcheetah [--workers 2]

rrls trains and evaluates on Gymnasium v5 with the derived constants recomputed after every
mass write (``mj_setConst``); the paper's code wrote the parameters without recomputing them
(``--physics paper``, ``docs/differences.md``). Each run's ``policy.npz`` is evaluated under the
folder's benchmark protocol with only ``physics`` changed to ``paper`` (its mesh, episodes and
seeds), and its worst and average case written beside the shipped (v5) ones to
``paper_physics.csv`` in the folder, one row per run as it finishes, every algorithm's seed 0
first (a re-run skips the runs already there; several processes share the work). The results
page's ``physics`` block (``benchmarks/results_page.py``) reads it.
"""

from __future__ import annotations

import argparse
import csv
import json
import time
from pathlib import Path

from rrls.benchmark import benchfile
from rrls.evaluation import evaluate

COLUMNS = (
    "run",
    "algorithm",
    "seed",
    "worst_case_v5",
    "average_case_v5",
    "worst_case_paper",
    "average_case_paper",
    "seconds",
)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("folder", type=Path)
    parser.add_argument("--workers", type=int, default=1)
    args = parser.parse_args()
    spec = benchfile.read_spec(args.folder)
    protocol = spec.protocol.replace(physics="paper")
    out = args.folder / "paper_physics.csv"
    if not out.exists():
        out.write_text(",".join(COLUMNS) + "\n")
    runs = sorted((args.folder / "runs").iterdir())
    runs.sort(key=lambda r: int(r.name.rpartition("seed")[2]))  # every algorithm's seed 0 first
    for run in runs:
        with open(out, newline="") as f:
            done = {row["run"] for row in csv.DictReader(f)}
        claim = args.folder / f".paper_physics.{run.name}.claim"
        if run.name in done:
            continue
        try:  # several processes may share the folder: each run once
            claim.touch(exist_ok=False)
        except FileExistsError:
            continue
        shipped = json.loads((run / "result.json").read_text())
        start = time.time()
        result = evaluate(
            run / "policy.npz", shipped["task"], protocol=protocol, workers=args.workers
        )
        row = [
            run.name,
            shipped["algorithm"],
            shipped["seed"],
            shipped["worst_case"],
            shipped["average_case"],
            result.worst_case,
            result.average_case,
            round(time.time() - start, 1),
        ]
        with open(out, "a", newline="") as f:
            csv.writer(f).writerow(row)
        claim.unlink()
        print(*row, flush=True)


if __name__ == "__main__":
    main()
