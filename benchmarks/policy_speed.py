"""The exact MLP policy's forward pass (``MLPPolicy``: exact-order products, exact tanh), in
microseconds per call and per row, at the batch sizes an evaluation runs (a lane block of 64,
a worker's 1 000) and one row (a training loop's act), for a HalfCheetah-sized 17-256-256-6 actor.

    python3 benchmarks/policy_speed.py                       # this checkout
    PYTHONPATH=/path/to/other/checkout python3 benchmarks/policy_speed.py   # a reference

Run the two in turn, several times, on a quiet machine and compare the medians. Prints a
markdown table.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

import rrls
from rrls.evaluation.policies import MLPPolicy


def median_us(policy: MLPPolicy, batch: int, calls: int) -> float:
    obs = np.random.default_rng(batch).normal(size=(batch, 17))
    policy(obs)  # work buffers of this batch size
    times = []
    for _ in range(calls):
        start = time.perf_counter()
        policy(obs)
        times.append(time.perf_counter() - start)
    return float(np.median(times)) * 1e6


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--calls", type=int, default=200)
    parser.add_argument("--batches", nargs="+", type=int, default=[1, 64, 1000])
    args = parser.parse_args()
    policy = MLPPolicy.random(17, 6, (256, 256), seed=0)
    print(f"rrls from {rrls.__file__}")
    print("| batch | us per call (median) | us per row |")
    print("|---|---|---|")
    for batch in args.batches:
        us = median_us(policy, batch, args.calls if batch < 1000 else max(20, args.calls // 10))
        print(f"| {batch} | {us:,.1f} | {us / batch:,.2f} |", flush=True)


if __name__ == "__main__":
    main()
