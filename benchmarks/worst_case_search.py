"""Worst-case search vs the grid: does the optimiser find a worse point with fewer episodes?

For a fixed policy (an MLP with fixed random weights), compares the 10^d mesh's worst case (one
episode per point, seed 0) with ``search_worst_case`` (differential evolution, one episode per
candidate with the same seeds, a budget below 10^d), side by side:

    python benchmarks/worst_case_search.py [--task hopper] [--uncertainty 3d] [--budget 400]
"""

from __future__ import annotations

import argparse
import time
import warnings

import gymnasium as gym

import rrls  # noqa: F401
from rrls.evaluation import MLPPolicy, evaluate, search_worst_case


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--task", default="hopper")
    parser.add_argument("--uncertainty", default="3d")
    parser.add_argument("--budget", type=int, default=400)
    parser.add_argument("--policy-seeds", type=int, nargs="+", default=[0, 1, 2])
    args = parser.parse_args()
    warnings.simplefilter("ignore")
    env = gym.make(f"rrls/robust-{args.task}-v0")
    obs_dim, act_dim = env.observation_space.shape[0], env.action_space.shape[0]

    print(
        f"\n{args.task}/{args.uncertainty}, MLP 64-64 with fixed random weights, 1 episode per "
        f"point, seed 0\n"
    )
    print(
        "| policy seed | grid worst (10^d points) | search worst (budget) | found worse? | "
        "episodes grid / search | time grid / search |"
    )
    print("|---|---|---|---|---|---|")
    for policy_seed in args.policy_seeds:
        policy = MLPPolicy.random(obs_dim, act_dim, hidden=(64, 64), seed=policy_seed)
        start = time.perf_counter()
        grid = evaluate(
            policy, args.task, args.uncertainty, mesh=10, episodes=1, seed=0, progress=False
        )
        t_grid = time.perf_counter() - start
        start = time.perf_counter()
        found = search_worst_case(
            policy, args.task, args.uncertainty, budget=args.budget, episodes=1, seed=0
        )
        t_search = time.perf_counter() - start
        point = ", ".join(f"{k}={v:.3g}" for k, v in found.params.items())
        print(
            f"| {policy_seed} | {grid.worst_case:.3f} | {found.value:.3f} at {point} | "
            f"{'yes' if found.value < grid.worst_case else 'no'} | "
            f"{len(grid.episodes)} / {found.episode_evaluations} | "
            f"{t_grid:.1f} s / {t_search:.1f} s |"
        )


if __name__ == "__main__":
    main()
