"""Do the rrls commits that trained a reference's runs train the same way? A reference produced
in pieces comes from several commits; this trains every algorithm of a preset for a few steps
at each commit (same seed, same machine) and compares the final weights and curves bit for bit.

    python3 benchmarks/same_training.py --preset halfcheetah --commits ca42dfc 26468a0 d6285a2 \\
        --work /tmp/same-training --csv docs/results/halfcheetah/same_training.csv

Each commit is checked out as a git worktree under ``--work`` and runs ``rrls benchmark
--preset P --seeds 0-0 --steps 3000 --learning-starts 1000`` (a short run: the warm-up shortened
so that 2 000 steps learn; resumable: run it again). Printed and written per (commit,
algorithm): worst and average case of the tiny mesh, and SHA-256 of the policy's weights and of
the curves (``scalars.csv`` without the speed rows). Equal hashes across commits: the same
training code path for that algorithm, on that machine.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd

ROOT = Path(__file__).resolve().parent.parent
SHORT = ["--seeds", "0-0", "--steps", "3000", "--learning-starts", "1000", "--eval-every", "1000"]
SHORT += ["--mesh", "2", "--episodes", "1", "--workers", "1", "--yes"]


def weights_sha(run: Path) -> str:
    """The policy's arrays (not its metadata header, which names the commit)."""
    with np.load(run / "policy.npz") as policy:
        arrays = [policy[k].tobytes() for k in sorted(policy.files) if k != "header"]
    return hashlib.sha256(b"".join(arrays)).hexdigest()


def curves_sha(run: Path) -> str:
    """The curves without the wall-clock speed rows."""
    scalars = pd.read_csv(run / "scalars.csv")
    scalars = scalars[scalars.metric != "charts/steps_per_second"]
    return hashlib.sha256(scalars.to_csv(index=False).encode()).hexdigest()


def train(commit: str, preset: str, work: Path) -> Path:
    """The short benchmark at ``commit`` (its own worktree), resumed if it exists."""
    tree, out = work / f"tree-{commit}", work / f"bench-{commit}"
    if not tree.exists():
        subprocess.run(["git", "worktree", "add", "--detach", str(tree), commit], cwd=ROOT,
                       check=True)  # fmt: skip
    env = {**os.environ, "PYTHONPATH": str(tree)}
    command = [sys.executable, "-m", "rrls", "benchmark", "--preset", preset, "--out", str(out)]
    subprocess.run(command + SHORT, cwd=work, env=env, check=True, stdout=subprocess.DEVNULL)
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--preset", default="halfcheetah")
    parser.add_argument("--commits", nargs="+", required=True)
    parser.add_argument("--work", type=Path, required=True, help="worktrees and benchmarks")
    parser.add_argument("--csv", type=Path, help="write the table here too")
    args = parser.parse_args(argv)
    args.work.mkdir(parents=True, exist_ok=True)
    rows = []
    for commit in args.commits:
        out = train(commit, args.preset, args.work)
        for result in sorted(out.glob("runs/*/result.json")):
            info = json.loads(result.read_text())
            rows.append({
                "commit": commit, "algorithm": info["algorithm"],
                "worst_case": info["worst_case"], "average_case": info["average_case"],
                "weights_sha256": weights_sha(result.parent),
                "curves_sha256": curves_sha(result.parent),
            })  # fmt: skip
    table = pd.DataFrame(rows)
    print("| algorithm | " + " | ".join(args.commits) + " | same weights and curves |")
    print("|---|" + "---|" * (len(args.commits) + 1))
    for algo, group in table.groupby("algorithm", sort=False):
        cells = [f"{r.worst_case:.3f} / {r.average_case:.3f}" for r in group.itertuples()]
        same = group.weights_sha256.nunique() == 1 and group.curves_sha256.nunique() == 1
        print(f"| {algo} | " + " | ".join(cells) + f" | {'yes' if same else 'no'} |")
    if args.csv:
        table.to_csv(args.csv, index=False)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
