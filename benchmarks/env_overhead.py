"""Step overhead of the robust envs against the plain Gymnasium v5 envs, and `import rrls` cost.

Both envs of a pair are stepped side by side in one run, in alternating rounds, with the same
pre-drawn actions; the table reports medians over rounds and the ratio robust / plain.
Target (issues 2 and 20): <= 5 % step overhead, with every parameter kind in the tables (the
robust env reports all its parameters in ``info`` at every step). On a loaded machine use short,
many rounds (``--steps 200 --rounds 60``): the ratio is taken round by round.

    python3 benchmarks/env_overhead.py [--steps 1000] [--rounds 15]
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import time
import warnings

import gymnasium as gym
import numpy as np

import rrls  # noqa: F401
from rrls.envs.base import mujoco_warnings_to_python
from rrls.tasks import TASKS


def steps_per_second(env: gym.Env, actions: np.ndarray) -> float:
    env.reset(seed=0)
    start = time.perf_counter()
    for a in actions:
        _, _, terminated, truncated, _ = env.step(a)
        if terminated or truncated:
            env.reset()
    return len(actions) / (time.perf_counter() - start)


def import_cost(rounds: int) -> tuple[float, float]:
    """Median time of `import gymnasium, mujoco` with and without `import rrls` (fresh procs)."""

    def timed(code: str) -> float:
        out = subprocess.run(
            [
                sys.executable,
                "-c",
                f"import time; t=time.perf_counter(); {code}; print(time.perf_counter()-t)",
            ],
            capture_output=True,
            text=True,
            check=True,
            env={"RRLS_NO_AUTOREGISTER": "1", "PATH": ""},
        )
        return float(out.stdout.strip().splitlines()[-1])

    base, ours = [], []
    for _ in range(rounds):
        base.append(timed("import gymnasium, mujoco"))
        ours.append(timed("import gymnasium, mujoco, rrls"))
    return statistics.median(base), statistics.median(ours)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=1000)
    parser.add_argument("--rounds", type=int, default=15)
    parser.add_argument("--tasks", nargs="*", help="only these tasks (default: every task)")
    parser.add_argument("--no-import", action="store_true", help="skip the import-cost line")
    args = parser.parse_args()

    print(f"{'task':<18}{'v5 steps/s':>12}{'robust steps/s':>16}{'ratio':>8}{'overhead':>10}")
    for key, task in TASKS.items():
        if args.tasks and key not in args.tasks:
            continue
        # HalfCheetah's XML uses the deprecated settotalmass: keep MUJOCO_LOG.TXT out of the cwd
        with warnings.catch_warnings(), mujoco_warnings_to_python():
            warnings.simplefilter("ignore")
            plain = gym.make(task.v5_id)
            robust = gym.make(f"rrls/robust-{key}-v0")
        rng = np.random.default_rng(0)
        space = plain.action_space
        actions = rng.uniform(space.low, space.high, (args.steps, *space.shape)).astype(space.dtype)
        steps_per_second(plain, actions[:200]), steps_per_second(robust, actions[:200])  # warm-up
        a, b = [], []
        for _ in range(args.rounds):
            a.append(steps_per_second(plain, actions))
            b.append(steps_per_second(robust, actions))
        pa, pb = statistics.median(a), statistics.median(b)
        ratios = statistics.median(y / x for x, y in zip(a, b))
        print(f"{key:<18}{pa:>12,.0f}{pb:>16,.0f}{ratios:>8.3f}{(1 - ratios) * 100:>9.1f}%")

    if args.no_import:
        return
    base, ours = import_cost(args.rounds)
    print(
        f"\nimport gymnasium, mujoco: {base * 1e3:.0f} ms; with rrls: {ours * 1e3:.0f} ms "
        f"(rrls adds {(ours - base) * 1e3:.0f} ms; target < 300 ms)"
    )


if __name__ == "__main__":
    main()
