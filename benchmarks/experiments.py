"""``rrls benchmark``'s local backend: throughput with 2 jobs against one run alone, and the
driver's own overhead, side by side.

(a) one run alone with the default settings: ``python -m rrls train`` (torch uses the idle
    cores: all of them when alone), TD3 on Hopper, ``--steps`` steps;
(b) the local backend with ``--jobs`` runs at a time: a grid of ``jobs`` runs of the same
    configuration (seeds 0..jobs-1), each in its own process, single-threaded, with a minimal
    final evaluation (mesh 1, one episode) and no periodic evaluation.

Throughput is training env steps per second summed over runs, from wall time (process start-up
included in both). Overhead of (b): the scheduler's latency (wall of the pool minus the longest
run's lifetime), the driver's CPU time while runs train (taken from them), and the time to build
the store and the report; as a share of the benchmark's wall time.

Targets (issue 13): (b) >= 1.8x (a) on 2 cores; overhead < 2 % of wall time.

    python benchmarks/experiments.py [--task hopper] [--algo td3] [--steps 6000]
                                     [--learning-starts 1000] [--jobs 2] [--rounds 1]
"""

from __future__ import annotations

import argparse
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def one_run_alone(args: argparse.Namespace, out: Path) -> float:
    """Wall seconds of ``rrls train`` with its defaults (a fresh process)."""
    cmd = [
        sys.executable, "-m", "rrls", "train", "--algo", args.algo, "--task", args.task,
        "--steps", str(args.steps), "--learning-starts", str(args.learning_starts),
        "--eval-every", "0", "--seed", "0", "--out", str(out),
    ]  # fmt: skip
    env = {
        **os.environ,
        "PYTHONPATH": os.pathsep.join([str(REPO), os.environ.get("PYTHONPATH", "")]),
    }
    start = time.perf_counter()
    subprocess.run(cmd, check=True, env=env, cwd=REPO, stdout=subprocess.DEVNULL)
    return time.perf_counter() - start


def local_backend(args: argparse.Namespace, out: Path) -> dict[str, float]:
    """Wall time of the pool, the longest run, the driver's CPU, store and report times."""
    from rrls.benchmark.backends import run_local
    from rrls.benchmark.grid import make_spec
    from rrls.benchmark.store import build_store
    from rrls.report.writer import make_report

    spec = make_spec(
        "paper",
        algos=args.algo,
        tasks=args.task,
        uncertainty="2d" if args.task == "invertedpendulum" else "3d",
        seeds=args.jobs,
        steps=args.steps,
        learning_starts=args.learning_starts,
        eval_every=0,
        mesh=1,
        episodes=1,
        dynamic_episodes=1,
    )
    started: dict = {}
    lifetimes: list[float] = []

    def on_event(key: object, state: str, detail: str) -> None:
        if state == "running":
            started[key] = time.perf_counter()
        else:
            if state == "failed":
                raise RuntimeError(f"{key} failed: {detail}")
            lifetimes.append(time.perf_counter() - started[key])

    cpu0 = resource.getrusage(resource.RUSAGE_SELF)
    t0 = time.perf_counter()
    run_local(out, spec, spec.runs(), args.jobs, on_event, lambda: None)
    pool = time.perf_counter() - t0
    cpu1 = resource.getrusage(resource.RUSAGE_SELF)
    t1 = time.perf_counter()
    build_store(out)
    store = time.perf_counter() - t1
    t2 = time.perf_counter()
    make_report(out)
    report = time.perf_counter() - t2
    driver_cpu = (cpu1.ru_utime - cpu0.ru_utime) + (cpu1.ru_stime - cpu0.ru_stime)
    return {
        "pool": pool,
        "longest": max(lifetimes),
        "driver_cpu": driver_cpu,
        "store": store,
        "report": report,
        "wall": pool + store + report,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--task", default="hopper")
    parser.add_argument("--algo", default="td3")
    parser.add_argument("--steps", type=int, default=6_000)
    parser.add_argument("--learning-starts", type=int, default=1_000)
    parser.add_argument("--jobs", type=int, default=2)
    parser.add_argument("--rounds", type=int, default=1)
    args = parser.parse_args()

    alone, pooled = [], []
    for _ in range(args.rounds):
        with tempfile.TemporaryDirectory() as tmp:
            alone.append(one_run_alone(args, Path(tmp) / "alone"))
            pooled.append(local_backend(args, Path(tmp) / "bench"))
    a = statistics.median(alone)
    b = {k: statistics.median(r[k] for r in pooled) for k in pooled[0]}
    sps_a = args.steps / a
    sps_b = args.jobs * args.steps / b["pool"]
    print(
        f"\n{args.algo} on {args.task}, {args.steps:,} steps per run ({args.learning_starts:,} "
        f"random), {os.cpu_count()} cores, median of {args.rounds} round(s)\n"
    )
    print(f"{'setting':<52} {'runs':>4} {'wall (s)':>9} {'env steps/s':>12} {'ratio':>6}")
    print(f"{'(a) one run alone, rrls train defaults':<52} {1:>4} {a:>9.1f} {sps_a:>12.0f} "
          f"{1.0:>5.2f}x")  # fmt: skip
    label = f"(b) local backend, --jobs {args.jobs}, 1 thread per run"
    print(f"{label:<52} {args.jobs:>4} {b['pool']:>9.1f} {sps_b:>12.0f} {sps_b / sps_a:>5.2f}x")
    latency = max(0.0, b["pool"] - b["longest"])
    overhead = latency + b["driver_cpu"] + b["store"] + b["report"]
    print(
        f"\noverhead of (b): scheduler latency {latency:.2f} s, driver CPU {b['driver_cpu']:.2f} s,"
        f" store {b['store']:.2f} s, report {b['report']:.2f} s = {overhead:.2f} s, "
        f"{100 * overhead / b['wall']:.1f} % of {b['wall']:.1f} s wall (target < 2 %)"
    )
    print(f"throughput ratio (b)/(a): {sps_b / sps_a:.2f}x (target >= 1.8x)")


if __name__ == "__main__":
    main()
