"""Every shipped policy of a results folder re-evaluated on the paper's physics (evaluation only).

    python3 benchmarks/paper_physics.py docs/results/halfcheetah [--workers 2]

rrls trains and evaluates on Gymnasium v5 with the derived constants recomputed after every
mass write (``mj_setConst``); the paper's code wrote the parameters without recomputing them
(``--physics paper``, ``docs/differences.md``). Each run's ``policy.npz`` is evaluated under the
folder's benchmark protocol with only ``physics`` changed to ``paper`` (its mesh, episodes and
seeds), and its worst and average case written beside the shipped (v5) ones to
``paper_physics.csv`` in the folder, one row per run as it finishes, every algorithm's seed 0
first (a re-run skips the runs already there; several processes share the work). A run's
evaluation keeps its finished chunks in ``.paper_physics/<run>/`` until its row is written, so a
process stopped part-way (Ctrl-C, a machine gone) goes on from them when run again; a run is
claimed with a lock that ends with its process, so no claim outlives it. ``seconds`` is the
evaluation's wall time over all its pieces (each piece adds its own to ``.paper_physics/<run>/
seconds`` as it stops); it is left empty where a piece's time was lost (a machine gone), so no
row states less time than its run took. The results page's ``physics`` block
(``benchmarks/results_page.py``) reads it.
"""

from __future__ import annotations

import argparse
import csv
import fcntl
import json
import shutil
import time
from pathlib import Path
from typing import Any

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
        claim = args.folder / f".paper_physics.{run.name}.claim"
        if run.name in written(out):
            continue
        hold = take(claim)  # several processes share the folder: each run once
        if hold is None:
            continue
        if run.name in written(out):  # by the process that held it until just now
            claim.unlink(missing_ok=True)
            hold.close()
            continue
        shipped = json.loads((run / "result.json").read_text())
        chunks = args.folder / ".paper_physics" / run.name  # resumable until its row is written
        spent = spent_before(chunks)
        (chunks / "seconds").unlink(missing_ok=True)  # a piece that dies unseen leaves no time
        start = time.time()
        try:
            result = evaluate(
                run / "policy.npz",
                shipped["task"],
                protocol=protocol,
                workers=args.workers,
                out_dir=chunks,
            )
        except BaseException:  # Ctrl-C and errors: this piece's time goes with the chunks
            if spent is not None and chunks.is_dir():
                (chunks / "seconds").write_text(f"{spent + time.time() - start:.1f}")
            raise
        row = [
            run.name,
            shipped["algorithm"],
            shipped["seed"],
            shipped["worst_case"],
            shipped["average_case"],
            result.worst_case,
            result.average_case,
            "" if spent is None else round(spent + time.time() - start, 1),
        ]
        with open(out, "a", newline="") as f:
            csv.writer(f).writerow(row)
        shutil.rmtree(chunks)
        claim.unlink()
        hold.close()
        print(*row, flush=True)


def spent_before(chunks: Path) -> float | None:
    """The seconds earlier pieces of a run's evaluation took: 0 for a fresh start, None where
    chunks exist without their time (a piece stopped without saying, or run before pieces were
    timed)."""
    if not chunks.is_dir() or not any(chunks.iterdir()):
        return 0.0
    try:
        return float((chunks / "seconds").read_text())
    except (OSError, ValueError):
        return None


def written(out: Path) -> set[str]:
    """The runs with a row in ``out``."""
    with open(out, newline="") as f:
        return {row["run"] for row in csv.DictReader(f)}


def take(claim: Path) -> Any:
    """This process's hold on a run, or None where another process holds it: an exclusive
    ``flock`` on the claim file, which ends with its process (a process stopped part-way leaves
    no claim behind)."""
    handle = open(claim, "a")  # held for the run's evaluation
    try:
        fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        handle.close()
        return None
    return handle


if __name__ == "__main__":
    try:
        main()
    except KeyboardInterrupt:  # the finished chunks stay: the same command goes on from them
        raise SystemExit("paper_physics: interrupted; run the same command to go on") from None
