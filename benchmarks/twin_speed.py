"""The Warp twin's whole env step (physics, observation, reward, termination, autoreset with a
new DR point per episode), env steps/s per world count, against the physics alone.

    python3 benchmarks/twin_speed.py --device cuda --worlds 32 256 1024 4096 8192
    python3 benchmarks/twin_speed.py --device cpu --worlds 4 --steps 5     # the dry run

``WarpTwin.step`` with device arrays in and out (``array="warp"``): on a GPU the step is one
CUDA graph. Actions are uniform random, drawn once per world and held (the timing does not depend
on them); domain randomization is on, so worlds that end draw a new point from the pool.
"""

from __future__ import annotations

import argparse
import time
import warnings

import numpy as np

from rrls.twin import WarpTwin


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--device", default="cuda")
    parser.add_argument("--tasks", nargs="+", default=["hopper", "halfcheetah"])
    parser.add_argument("--worlds", nargs="+", type=int, default=[32, 256, 1024, 4096, 8192])
    parser.add_argument("--steps", type=int, default=200, help="timed env steps")
    args = parser.parse_args()
    warnings.simplefilter("ignore")
    import warp as wp

    print("| task | worlds | env steps/s (whole step, DR) | episodes ended |")
    print("|---|---|---|---|")
    for task in args.tasks:
        for n in args.worlds:
            twin = WarpTwin(task, n, domain_randomization=True, device=args.device, array="warp")
            twin.reset(seed=0)
            rng = np.random.default_rng(0)
            low, high = twin.single_action_space.low, twin.single_action_space.high
            actions = wp.array(
                rng.uniform(low, high, size=(n, len(low))).astype(np.float32),
                dtype=float,
                device=twin.device,
            )
            for _ in range(5):  # compile, capture
                twin.step(actions)
            wp.synchronize()
            ended = 0
            start = time.perf_counter()
            for _ in range(args.steps):
                twin.step(actions)
            wp.synchronize()
            wall = time.perf_counter() - start
            ended = int(twin.episode.numpy().sum()) - n
            print(f"| {task} | {n} | {n * args.steps / wall:,.0f} | {ended} |", flush=True)
            twin.close()


if __name__ == "__main__":
    main()
