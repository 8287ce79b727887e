"""The paper's five baselines sharing one Warp twin step (``rrls.agents.shared``): ``K`` seeds of
each on one task, trained together with run directories as ``rrls train`` writes them, run 0
(TD3 seed 0) in ``OUT/seed0`` so that the GPU runbook reads its rate where it reads every
step's (``charts/steps_per_second`` of ``OUT/seed0/scalars.csv``), the others in
``OUT/<algo>-seed<S>``.

    python3 benchmarks/twin_shared.py OUT --task hopper --k 10 --steps 2000 --starts 500
    python3 benchmarks/twin_shared.py OUT --device cpu --k 1 --steps 60 --starts 20  # dry run
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path


def configs(args: argparse.Namespace) -> list:
    """Every run's settings: the paper's five, ``--k`` seeds each, on one twin."""
    from rrls.agents import TrainConfig
    from rrls.algorithms import paper_five

    out = []
    for algo in paper_five():
        for seed in range(args.k):
            where = "seed0" if not out else f"{algo}-seed{seed}"
            out.append(
                TrainConfig(
                    algo=algo,
                    task=args.task,
                    seed=seed,
                    steps=args.steps,
                    out=str(args.out / where),
                    uncertainty="3d",
                    device=args.device,
                    simulator="warp",
                    eval_every=0,
                    checkpoint_every=10 * args.steps,
                    overwrite=True,
                    progress=False,
                    hyper={"learning_starts": args.starts},
                )
            )
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", type=Path, metavar="OUT_DIR")
    parser.add_argument("--task", default="hopper")
    parser.add_argument("--k", type=int, default=10, help="seeds per algorithm")
    parser.add_argument("--steps", type=int, default=2_000, help="env steps per run")
    parser.add_argument("--starts", type=int, default=500, help="random steps before learning")
    parser.add_argument("--device", default="cuda")
    args = parser.parse_args(argv)
    from rrls.agents import train_group

    dirs = train_group(configs(args))
    print(f"{len(dirs)} runs of the paper's five baselines on one {args.task} twin: {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
