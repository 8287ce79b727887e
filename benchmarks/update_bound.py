"""What separates an update from the compute bound: its matrix products against everything else.

For each algorithm (``--algos``, default CleanRL's TD3, rrls TD3, CleanRL's SAC, rrls SAC,
M2TD3) and thread count (``--threads``, default 1 2), a real ``rrls train`` run on Hopper
(1 000 random steps first; CleanRL's rows: its published loop, ``cleanrl_loops.published``)
whose learner's ``update`` is wrapped: after ``--warmup`` updates, ``--updates`` are timed one
by one (median), then ``--profiled`` more run under ``torch.profiler``, which gives the share
of the update spent in matrix products (``bmm``/``baddbmm``/``mm``/``addmm`` self time) and
their FLOPs (from the recorded shapes). The bound is those FLOPs at this machine's measured
matrix-product rate (a ``(2, 256, 256) x (2, 256, 256)`` ``bmm``, the paper's critic layer,
with the same threads): an update of nothing but its products at full speed.

    python benchmarks/update_bound.py [--algos cleanrl td3 cleanrl-sac sac m2td3] [--threads 1 2]

Prints one table: update ms, products ms (share), the rest, GFLOP per update, the bound,
updates/s against it. Run it on a quiet machine; each row is a fresh process.
"""

from __future__ import annotations

import argparse
import math
import multiprocessing
import statistics
import tempfile
import time
import warnings

import torch

GEMMS = {"aten::bmm", "aten::baddbmm", "aten::mm", "aten::addmm"}


def gemm_rate(threads: int) -> float:
    """GFLOP/s of the paper's critic layer as one ``bmm`` (both critics), median of 7."""
    torch.set_num_threads(threads)
    a, b = torch.randn(2, 256, 256), torch.randn(2, 256, 256)
    for _ in range(20):
        torch.bmm(a, b)
    times = []
    for _ in range(7):
        start = time.perf_counter()
        for _ in range(100):
            torch.bmm(a, b)
        times.append((time.perf_counter() - start) / 100)
    return 2 * 2 * 256**3 / statistics.median(times) / 1e9


def flops(event) -> float:
    """FLOPs of one recorded matrix product from its input shapes."""
    shapes = [s for s in event.input_shapes if s]
    if event.key in ("aten::baddbmm", "aten::addmm"):
        shapes = shapes[1:3]
    (*batch, m, k), (*_, n) = shapes[0], shapes[1]
    return 2.0 * math.prod(batch) * m * k * n


def measure(algo: str, threads: int, warmup: int, updates: int, profiled: int) -> dict:
    """One row, in this (fresh) process."""
    from torch.profiler import profile

    from rrls.agents.lookup import algorithm

    warnings.simplefilter("ignore")
    if algo.startswith("cleanrl"):  # CleanRL's own loop and update (cleanrl_loops.py)
        import cleanrl_loops

        learner = cleanrl_loops.CleanRLSAC if algo == "cleanrl-sac" else cleanrl_loops.CleanRLTD3
    else:
        learner = algorithm(algo).Learner
    plain = learner.update
    times: list[float] = []
    record: dict = {"n": 0}

    def update(self, *args):
        if record["n"] < warmup:
            record["n"] += 1
            return plain(self, *args)
        if len(times) < updates:
            start = time.perf_counter()
            out = plain(self, *args)
            times.append(time.perf_counter() - start)
            return out
        if "profile" not in record:
            record["profile"] = profile(record_shapes=True)
            record["profile"].__enter__()
            record["left"] = profiled
        out = plain(self, *args)
        record["left"] -= 1
        if record["left"] == 0:
            record["profile"].__exit__(None, None, None)
        return out

    learner.update = update
    try:
        if algo.startswith("cleanrl"):
            torch.set_num_threads(threads)
            cleanrl_loops.published(
                algo.partition("-")[2] or "td3", "hopper", updates + profiled, warmup
            )
        else:
            train_for(algo, threads, warmup + updates + profiled)
    finally:
        learner.update = plain
    return summary(record, times, profiled, threads)


def train_for(algo: str, threads: int, updates: int) -> None:
    """``rrls train`` on Hopper: 1 000 random steps, then ``updates`` updates."""
    from group_speed import timed_config

    from rrls.agents import train

    with tempfile.TemporaryDirectory() as out:
        train(timed_config(algo, "hopper", 1000 + updates + 1, out, 1000, threads, None))


def summary(record: dict, times: list[float], profiled: int, threads: int) -> dict:
    """The row's figures from the timed and the profiled updates."""
    events = record["profile"].key_averages(group_by_input_shape=True)
    total = sum(e.self_cpu_time_total for e in events)
    gemm = sum(e.self_cpu_time_total for e in events if e.key in GEMMS)
    work = sum(flops(e) * e.count for e in events if e.key in GEMMS) / profiled
    return {
        "update": statistics.median(times),
        "share": gemm / total,
        "gflop": work / 1e9,
        "rate": gemm_rate(threads),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--algos",
        nargs="+",
        default=["cleanrl", "td3", "cleanrl-sac", "sac", "m2td3"],
        help="rrls algorithms, and cleanrl / cleanrl-sac: CleanRL's TD3 / SAC update",
    )
    parser.add_argument("--threads", type=int, nargs="+", default=[1, 2])
    parser.add_argument("--warmup", type=int, default=1000)
    parser.add_argument("--updates", type=int, default=500)
    parser.add_argument("--profiled", type=int, default=100)
    args = parser.parse_args()
    ctx = multiprocessing.get_context("spawn")
    rows = []
    for algo in args.algos:
        for threads in args.threads:
            with ctx.Pool(1) as pool:
                job = (algo, threads, args.warmup, args.updates, args.profiled)
                rows.append((algo, threads, pool.apply(measure, job)))
    print(
        f"\nHopper, 256-256, one update per env step; median of {args.updates} updates after "
        f"{args.warmup}; products' share from {args.profiled} profiled updates\n"
    )
    print(
        "| algo | threads | update ms | products ms (share) | the rest ms | GFLOP / update "
        "| product rate GFLOP/s | bound ms | updates/s | bound updates/s | of the bound |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for algo, threads, r in rows:
        ms = r["update"] * 1e3
        bound = r["gflop"] / r["rate"] * 1e3
        print(
            f"| {algo} | {threads} | {ms:.2f} | {ms * r['share']:.2f} ({r['share']:.0%}) "
            f"| {ms * (1 - r['share']):.2f} | {r['gflop']:.3f} | {r['rate']:.0f} | {bound:.2f} "
            f"| {1e3 / ms:.0f} | {1e3 / bound:.0f} | {bound / ms:.0%} |"
        )


if __name__ == "__main__":
    main()
