"""The Warp twin's whole env step (physics, observation, reward, termination, autoreset with a
new DR point per episode), env steps/s per world count, against the physics alone.

    python3 benchmarks/twin_speed.py --device cuda --worlds 32 256 1024 4096 8192
    python3 benchmarks/twin_speed.py --device cpu --worlds 4 --steps 5     # the dry run

``WarpTwin.step`` with device arrays in and out (``array="warp"``): on a GPU the step is one
CUDA graph. Actions are uniform random, drawn once per world and held (the timing does not depend
on them); domain randomization is on, so worlds that end draw a new point from the pool.

With ``--fresh`` (the default), the same step again with ``pool=0``: each episode's point drawn
on the device from the whole box, its fields written there and MuJoCo Warp's ``set_const``
recomputing the derived constants (of every world, at every step: a captured graph cannot skip
it), and the ratio of the two rates, fresh against the pool: what retiring the pool costs.
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
    parser.add_argument(
        "--fresh",
        action=argparse.BooleanOptionalAction,
        default=True,
        help="also time pool=0 (a fresh point per episode on the device) and the ratio",
    )
    args = parser.parse_args()
    warnings.simplefilter("ignore")

    head = "| task | worlds | env steps/s (whole step, DR) | episodes ended |"
    rule = "|---|---|---|---|"
    if args.fresh:
        head += " env steps/s (pool=0) | pool=0 / pool |"
        rule += "---|---|"
    print(head)
    print(rule)
    for task in args.tasks:
        for n in args.worlds:
            rate, ended = timed(task, n, args.device, args.steps, 1024)
            row = f"| {task} | {n} | {rate:,.0f} | {ended} |"
            if args.fresh:
                fresh, _ = timed(task, n, args.device, args.steps, 0)
                row += f" {fresh:,.0f} | {fresh / rate:.2f} |"
            print(row, flush=True)


def timed(task: str, n: int, device: str, steps: int, pool: int) -> tuple[float, int]:
    """Env steps/s of ``n`` worlds over ``steps`` steps (after 5 to compile and capture), and
    the episodes that ended meanwhile."""
    import warp as wp

    twin = WarpTwin(task, n, domain_randomization=True, pool=pool, device=device, array="warp")
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
    start = time.perf_counter()
    for _ in range(steps):
        twin.step(actions)
    wp.synchronize()
    wall = time.perf_counter() - start
    ended = int(twin.episode.numpy().sum()) - n
    twin.close()
    return n * steps / wall, ended


if __name__ == "__main__":
    main()
