"""How long a benchmark takes on one GPU, from rrls's own GPU measurements.

``rrls benchmark --dry-run --device cuda`` prints this instead of the CPU estimate. The rates are
rrls's measured figures on one NVIDIA H100 (``docs/results/gpu/h100-2026-11-25.md``,
``benchmarks/train_speed.py --groups``; eager updates captured in CUDA graphs, Hopper, 4-15
env-worker processes on that machine's 16 cores): env steps per second after learning starts of
ONE process training K runs of a cell together. What is measured and what is extrapolated:

- measured: TD3 and M2TD3 at K = 1, 8 and 32 (one round each, ±25 % run to run);
- TD3's scaled by their CPU rate against TD3's (not measured on a GPU): DR (as TD3), RARL and
  NR-MDP (which train an adversary too: 0.49x and 0.89x), SAC, SAC-DR and plug-ins;
- interpolated between measured K (linearly in the aggregated rate) and, beyond K = 32, held at
  K = 32's per-run rate: extrapolated;
- groups run one after another (one process holds the GPU); the evaluation runs on the CPU
  cores (the CPU estimate's evaluation time divided among ``cpu_cores``);
- other tasks than Hopper: taken as Hopper's (the loop is bound by the update and the env
  workers, not by one task's physics; not measured).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from rrls.benchmark.cpu_estimate import REPORT_S, STARTUP_S, estimate
from rrls.benchmark.grid import Benchmark, RunKey

__all__ = ["GPU_RECORD", "Rate", "describe", "gpu_estimate", "stored_rate"]

#: ``rate(algo, task, k) -> (aggregated env steps/s, measured)``: where a group's rate comes from
Rate = Callable[[str, str, int], tuple[float, bool]]

#: where the figures come from
GPU_RECORD = "docs/results/gpu/h100-2026-11-25.md"


def stored_rate(algo: str, k: int) -> tuple[float, bool]:
    """Aggregated env steps/s of a group of ``k`` runs of ``algo``, and whether measured (its
    row's ``gpu_steps_per_s``, measured on one H100; a row without them: TD3's, times its CPU
    rate against TD3's, so that RARL's second player is counted)."""
    from rrls.algorithms import TD3_CPU, TD3_GPU, algorithm_info

    info = algorithm_info(algo)
    own = info.gpu_rate() if info is not None else {}
    scale = info.cpu_steps_per_s / TD3_CPU if info is not None else 1.0
    table = own or {n: r * scale for n, r in TD3_GPU}
    measured = bool(own) and k in table
    ks = sorted(table)
    if k in table:
        return table[k], measured
    if k > ks[-1]:  # beyond the largest measured K: its per-run rate, no further gain
        return table[ks[-1]] / ks[-1] * k, False
    lo = max(x for x in ks if x < k)
    hi = min(x for x in ks if x > k)
    w = (k - lo) / (hi - lo)
    return table[lo] * (1 - w) + table[hi] * w, False


def gpu_estimate(
    spec: Benchmark,
    pack: int,
    cpu_cores: int = 16,
    rate: Rate | None = None,
    shared: Callable[[str, int], tuple[float, bool]] | None = None,
) -> dict[str, Any]:
    """Seconds on one GPU: ``train_s`` (groups of ``pack`` seeds of a cell, one after another),
    ``eval_s`` (the final evaluations on ``cpu_cores``), ``wall_s``, and ``measured`` (whether
    every rate used was measured rather than interpolated, extrapolated or borrowed). ``rate``
    replaces the stored H100 figures (``benchmarks/gpu_runbook.py`` passes the rates it has
    just measured on the machine, per task). ``shared(task, runs) -> (aggregated env steps/s,
    measured)``: the rate of a task's algorithms sharing one twin step (``rrls benchmark
    --simulator warp`` packs them so: ``pipeline.groups``); given, those runs are timed as one
    group of each turn of ``pack`` seeds, at the steps of the longest warm-up's."""
    from rrls.benchmark.pipeline import shares_twin

    pack = max(1, min(pack, len(spec.seeds)))
    train, measured = 0.0, True
    groups = 0
    together = {
        task: [a for a in spec.algos if shares_twin(spec, RunKey(a, task, 0))]
        for task in spec.tasks
        if shared is not None
    }
    for algo in spec.algos:
        for task in spec.tasks:
            if algo in together.get(task, ()):
                continue
            for start in range(0, len(spec.seeds), pack):
                k = min(pack, len(spec.seeds) - start)
                per_s, exact = rate(algo, task, k) if rate else stored_rate(algo, k)
                measured &= exact
                learning = spec.steps - spec.warmup(algo)
                train += STARTUP_S + k * learning / per_s + spec.warmup(algo) / 2_000.0
                groups += 1
    for task, algos in together.items():
        for start in range(0, len(spec.seeds), pack) if shared and algos else ():
            runs = min(pack, len(spec.seeds) - start) * len(algos)
            per_s, exact = shared(task, runs)
            measured &= exact
            train += STARTUP_S + runs * spec.steps / per_s
            groups += 1
    evals = estimate(spec, 1)["eval_s"] / max(1, cpu_cores)
    return {
        "groups": groups,
        "train_s": train,
        "eval_s": evals,
        "wall_s": train + evals + REPORT_S,
        "measured": measured,
        "record": GPU_RECORD,
    }


def describe(spec: Benchmark, pack: int) -> str:
    """The dry run's estimate line for ``--device cuda``."""
    from rrls.benchmark.cpu_estimate import format_duration

    est = gpu_estimate(spec, pack)
    how = (
        "measured rates"
        if est["measured"]
        else "measured rates where they exist, others interpolated, extrapolated or scaled from "
        "TD3's"
    )
    return (
        f"estimate on one GPU (rrls's own H100 figures, {GPU_RECORD}; {how}; ±30 % at best): "
        f"{format_duration(est['wall_s'])} ({est['groups']} groups of up to {pack} runs one "
        f"after another: training {format_duration(est['train_s'])}, final evaluations on 16 "
        f"CPU cores {format_duration(est['eval_s'])})"
        + (
            "; counted a group per cell: how much a task's algorithms sharing each twin step "
            "save is not measured yet (benchmarks/gpu_runbook.py measures it)"
            if spec.simulator == "warp"
            else ""
        )
    )
