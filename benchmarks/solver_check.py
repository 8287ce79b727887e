"""HumanoidStandup under the solvers MuJoCo Warp implements, against its own PGS: can a twin
with another solver stand in for it?

HumanoidStandup's XML asks for MuJoCo's PGS constraint solver, which MuJoCo Warp does not
implement (it has CG and Newton). This steps CPU MuJoCo (float64, exact) from the same reset
state with the same uniformly random actions, once with the model as written (PGS) and once per
other solver, and writes, per seed and solver, the largest ``|qpos - qpos_PGS|`` after 1, 10 and
100 env steps and the 100-step returns of both, so the docs can say whether the twin could train
it under another solver (a different physics would be another protocol) or it trains on CPU
MuJoCo inside the same benchmark.

    python3 benchmarks/solver_check.py --out docs/results/twin/solver.csv
"""

from __future__ import annotations

import argparse
import csv
from pathlib import Path

import gymnasium as gym
import mujoco
import numpy as np

import rrls  # noqa: F401  (registers the rrls ids)

SOLVERS = {"CG": mujoco.mjtSolver.mjSOL_CG, "Newton": mujoco.mjtSolver.mjSOL_NEWTON}
AT = (1, 10, 100)


def rollout(seed: int, solver: int | None, actions: np.ndarray) -> tuple[list[np.ndarray], float]:
    """qpos after each env step and the return, from the seed's reset state."""
    env = gym.make("rrls/robust-humanoidstandup-v0")
    if solver is not None:
        env.unwrapped.model.opt.solver = solver
    env.reset(seed=seed)
    qpos, total = [], 0.0
    for a in actions:
        _, reward, terminated, truncated, _ = env.step(a)
        qpos.append(env.unwrapped.data.qpos.copy())
        total += float(reward)
        if terminated or truncated:
            break
    env.close()
    return qpos, total


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=5)
    parser.add_argument("--out", type=Path, default=Path("solver.csv"))
    args = parser.parse_args()
    space = gym.make("rrls/robust-humanoidstandup-v0").action_space
    rows = []
    for seed in range(args.seeds):
        actions = np.random.default_rng(seed).uniform(space.low, space.high, (max(AT), 17))
        pgs, pgs_return = rollout(seed, None, actions)
        for name, solver in SOLVERS.items():
            other, other_return = rollout(seed, solver, actions)
            row = {"seed": seed, "solver": name}
            for t in AT:
                row[f"qpos_gap_{t}"] = float(np.abs(other[t - 1] - pgs[t - 1]).max())
            row |= {"return_pgs": pgs_return, "return_solver": other_return}
            rows.append(row)
            print(row, flush=True)
    with args.out.open("w", newline="") as f:
        writer = csv.DictWriter(f, list(rows[0]), lineterminator="\n")
        writer.writeheader()
        writer.writerows(rows)


if __name__ == "__main__":
    main()
