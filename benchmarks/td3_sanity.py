"""Is rrls's TD3 learning a task as TD3 does elsewhere? Its curve beside CleanRL's (and, on
Hopper, the TD3 authors'), at the same step counts.

- ``--run``: CleanRL's ``td3_continuous_action.py`` loop as published (``cleanrl_loops``; its
  defaults: 25 000 random steps, 256-256, batch 256) on the same Hopper-v5 physics, ``--seeds``
  in parallel processes (one thread each) for ``--steps``; each training episode's return is
  written to ``--out`` (CSV: seed, step, return).
- then the table: at 50 k, 100 k, 150 k and 200 k steps, the mean training-episode return over
  the preceding 10 000 steps (with exploration noise, as CleanRL logs it) of rrls's TD3 runs
  (``docs/results/hopper-200k/runs/td3-*/scalars.csv``) and of CleanRL's; rrls's deterministic
  nominal evaluation; and the TD3 authors' published learning curves (Fujimoto et al. 2018,
  ``sfujim/TD3`` ``learning_curves/Hopper/TD3_Hopper-v1_{0..9}.npy``: Hopper-v1 under mujoco-py,
  10 seeds, 10 000 random steps, 400-300 networks, deterministic evaluation every 5 000 steps;
  ``AUTHORS`` below holds their mean and std at these steps, read from those files).

    python benchmarks/td3_sanity.py --run --seeds 0 1 2 --steps 200000   # ~25 min, 2 cores
    python benchmarks/td3_sanity.py                                      # the table only
    python benchmarks/td3_sanity.py --task halfcheetah --run --seeds 0 1 --steps 300000

``--task halfcheetah`` reads ``docs/results/halfcheetah/`` and writes its
``cleanrl_td3_returns.csv``, at 100 k, 200 k and 300 k steps (no published authors' column).
"""

from __future__ import annotations

import argparse
import csv
import multiprocessing
from pathlib import Path

import numpy as np
import pandas as pd

ROOT = Path(__file__).resolve().parent.parent
RUNS = ROOT / "docs" / "results" / "hopper-200k" / "runs"
OUT = ROOT / "docs" / "results" / "hopper-200k" / "cleanrl_td3_returns.csv"
STEPS = (50_000, 100_000, 150_000, 200_000)
WINDOW = 10_000
#: TD3 authors' Hopper-v1 evaluation returns (mean, std over 10 seeds) at STEPS
AUTHORS = {50_000: (285, 69), 100_000: (659, 752), 150_000: (1211, 856), 200_000: (2441, 746)}


#: per task: the step counts of the table and the TD3 authors' figures (None: not shipped)
TASKS = {
    "hopper": (STEPS, AUTHORS),
    "halfcheetah": ((100_000, 200_000, 300_000), None),
}
#: per task: the results folder whose TD3 runs the table reads
FOLDERS = {"hopper": "hopper-200k", "halfcheetah": "halfcheetah"}


def _one(job: tuple[int, int, str]) -> list[tuple[int, int, float]]:
    import warnings

    import torch
    from cleanrl_loops import published

    from rrls.envs.base import mujoco_warnings_to_python

    warnings.simplefilter("ignore")
    torch.set_num_threads(1)
    seed, steps, task = job
    returns: list[tuple[int, float]] = []
    with mujoco_warnings_to_python():  # not MUJOCO_LOG.TXT in the working directory
        published("td3", task, steps - 25_000 - 1, 0, seed, learning_starts=25_000, returns=returns)
    return [(seed, step, value) for step, value in returns]


def run(seeds: list[int], steps: int, out: Path, task: str = "hopper") -> None:
    with multiprocessing.get_context("spawn").Pool(len(seeds)) as pool:
        jobs = [(s, steps, task) for s in seeds]
        rows = [row for rows in pool.map(_one, jobs) for row in rows]
    out.parent.mkdir(parents=True, exist_ok=True)
    with open(out, "w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(["seed", "step", "return"])
        writer.writerows(rows)


def windowed(frame: pd.DataFrame, step: int) -> list[float]:
    """Per seed: the mean return of the episodes ending in ``(step - WINDOW, step]``."""
    part = frame[(frame["step"] > step - WINDOW) & (frame["step"] <= step)]
    return part.groupby("seed")["return"].mean().tolist()


def td3_curves(folder: Path) -> tuple[pd.DataFrame, pd.DataFrame]:
    """A results folder's TD3 runs: their training-episode returns (seed, step, return) and
    their nominal evaluations (``scalars.csv`` rows, with a seed column)."""
    train, nominal = [], []
    for path in sorted(folder.glob("runs/td3-*-seed*/scalars.csv")):
        seed = int(path.parent.name.rpartition("seed")[2])
        data = pd.read_csv(path)
        rets = data[data["metric"] == "charts/episode_return"]
        train.append(pd.DataFrame({"seed": seed, "step": rets["step"], "return": rets["value"]}))
        nominal.append(data[data["metric"] == "eval/nominal_return"].assign(seed=seed))
    return pd.concat(train), pd.concat(nominal)


def cell(values: list[float]) -> str:
    if not values:
        return "-"
    return f"{np.mean(values):.0f} ± {np.std(values):.0f} ({len(values)})"


def table(
    folder: Path = RUNS.parent,
    cleanrl: Path = OUT,
    steps: tuple[int, ...] = STEPS,
    authors: dict[int, tuple[int, int]] | None = None,
) -> str:
    """The side-by-side table (markdown) of a results folder's TD3 runs, CleanRL's loop's
    returns (``cleanrl``) and, where given, the TD3 authors' published figures."""
    authors = TASKS.get(folder.name, (steps, AUTHORS))[1] if authors is None else authors
    rrls, evals = td3_curves(folder)
    clean = (
        pd.read_csv(cleanrl)
        if cleanrl.is_file()
        else pd.DataFrame(columns=["seed", "step", "return"])
    )
    head = (
        "| steps | rrls TD3, training episodes | CleanRL TD3 loop, same physics, training "
        "episodes | rrls TD3, nominal evaluation |"
    )
    lines = [
        head + (" TD3 authors, evaluation |" if authors else ""),
        "|---" * (5 if authors else 4) + "|",
    ]
    for step in steps:
        ev = evals[evals["step"] == step]["value"].tolist()
        row = f"| {step:,} | {cell(windowed(rrls, step))} | {cell(windowed(clean, step))} | "
        row += f"{cell(ev)} |"
        if authors:
            mean, std = authors[step]
            row += f" {mean} ± {std} (10) |"
        lines.append(row)
    return "\n".join(lines) + "\n"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--task", choices=list(TASKS), default="hopper")
    parser.add_argument("--run", action="store_true", help="train CleanRL's loop first")
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    parser.add_argument("--steps", type=int, default=200_000)
    parser.add_argument("--out", type=Path, help="default: the task's results folder")
    args = parser.parse_args()
    folder = ROOT / "docs" / "results" / FOLDERS[args.task]
    out = args.out or folder / "cleanrl_td3_returns.csv"
    if args.run:
        run(args.seeds, args.steps, out, args.task)
    print(
        f"\n{args.task} TD3, return at the same steps: mean ± std over seeds (seeds); training "
        f"episodes: mean of those ending in the {WINDOW:,} steps before\n"
    )
    print(table(folder, out, TASKS[args.task][0]))


if __name__ == "__main__":
    main()
