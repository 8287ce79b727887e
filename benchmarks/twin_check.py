"""The Warp twin against CPU MuJoCo: the per-task, per-kind table and the divergence figure.

    python3 benchmarks/twin_check.py docs/results/twin            # warp's CPU device (~15 min)
    python3 benchmarks/twin_check.py OUT --device cuda             # on a GPU

Table (``check.csv``): for every twin task and every parameter kind it has, 4 worlds at 4 points
of a box around the nominal value of that kind's parameters (``rrls.twin.agreement.kind_set``),
random actions; the largest ``|qpos - qpos_cpu|`` after 1 and 10 env steps, ``|qvel - ...|``
after 10, the largest reward difference over the 10 steps and the worlds whose termination
differed.

Divergence (``divergence.csv``, ``divergence.png``): the task's largest paper set, 8 worlds,
1 000 env steps of random actions; per step the largest ``|qpos - qpos_cpu|`` over the worlds
still in their first episode (Hopper, Walker2d and Ant end episodes early under random actions:
their curves stop where the last world ends).
"""

from __future__ import annotations

import argparse
import csv
import time
import warnings
from pathlib import Path

import numpy as np

from rrls.twin import TWIN_TASKS
from rrls.twin.agreement import TWIN_KINDS, divergence, kind_set
from rrls.twin.env import default_set

HORIZON = 1000


def table(out: Path, device: str, tasks: list[str]) -> None:
    rows = []
    for task in tasks:
        for kind in TWIN_KINDS:
            try:
                box = kind_set(task, kind)
            except ValueError:
                continue  # the task has no parameter of this kind
            start = time.perf_counter()
            d = divergence(task, box, worlds=4, steps=10, device=device)
            rows.append(
                {
                    "task": task,
                    "kind": kind,
                    "parameters": len(box.names),
                    "qpos_1": d.qpos[0],
                    "qpos_10": np.nanmax(d.qpos[:10]),
                    "qvel_10": np.nanmax(d.qvel[:10]),
                    "reward_10": np.nanmax(d.reward[:10]),
                    "termination_mismatches": d.termination_mismatches,
                }
            )
            print(
                f"{task:16s} {kind:12s} qpos {d.qpos[0]:.1e} / {np.nanmax(d.qpos):.1e}  "
                f"qvel {np.nanmax(d.qvel):.1e}  reward {np.nanmax(d.reward):.1e}  "
                f"termination mismatches {d.termination_mismatches}  "
                f"({time.perf_counter() - start:.0f} s)",
                flush=True,
            )
    with (out / "check.csv").open("w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]))
        writer.writeheader()
        for row in rows:
            writer.writerow({k: f"{v:.3e}" if isinstance(v, float) else v for k, v in row.items()})


def markdown(path: Path) -> str:
    """``check.csv`` as the docs' table (the docs' copy is checked against this by a test)."""
    with path.open() as f:
        rows = list(csv.DictReader(f))
    lines = [
        "| task | kind | parameters | max dqpos, 1 step | max dqpos, 10 steps | max dqvel, "
        "10 steps | max dreward | terminations differing |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        lines.append(
            f"| {r['task']} | {r['kind']} | {r['parameters']} | {float(r['qpos_1']):.1e} | "
            f"{float(r['qpos_10']):.1e} | {float(r['qvel_10']):.1e} | "
            f"{float(r['reward_10']):.1e} | {r['termination_mismatches']} |"
        )
    return "\n".join(lines) + "\n"


def curves(out: Path, device: str, tasks: list[str]) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    series = {}
    for task in tasks:
        start = time.perf_counter()
        d = divergence(task, default_set(task), worlds=8, steps=HORIZON, device=device)
        series[task] = d.qpos
        alive = int(np.sum(~np.isnan(d.qpos)))
        print(f"{task}: {alive} steps compared ({time.perf_counter() - start:.0f} s)", flush=True)
    with (out / "divergence.csv").open("w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(["step", *series])
        for t in range(HORIZON):
            writer.writerow([t + 1, *(f"{series[k][t]:.3e}" for k in series)])
    fig, ax = plt.subplots(figsize=(6.4, 3.6))
    for task, q in series.items():
        ax.plot(np.arange(1, HORIZON + 1), q, label=task)
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("env steps")
    ax.set_ylabel("max |qpos twin - qpos CPU|")
    ax.set_title("Warp twin (float32) vs CPU MuJoCo (float64), 8 worlds each")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out / "divergence.png", dpi=120)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", type=Path)
    parser.add_argument("--device", default="cpu")
    parser.add_argument("--tasks", nargs="+", default=list(TWIN_TASKS), choices=list(TWIN_TASKS))
    parser.add_argument("--no-curves", dest="curves", action="store_false")
    parser.add_argument("--no-table", dest="table", action="store_false")
    args = parser.parse_args()
    warnings.simplefilter("ignore")
    args.out.mkdir(parents=True, exist_ok=True)
    if args.table:
        table(args.out, args.device, args.tasks)
    if args.curves:
        curves(args.out, args.device, args.tasks)


if __name__ == "__main__":
    main()
