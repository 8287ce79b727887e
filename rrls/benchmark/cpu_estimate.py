"""The CPU compute estimate of a benchmark (``rrls benchmark`` prints it before starting; the
dry run prints it alone): training and evaluation seconds per run from rates measured on this
project's machines, then the wall time with ``jobs`` runs at a time. Its GPU counterpart is
``gpu_estimate``."""

from __future__ import annotations

import heapq
from collections.abc import Mapping

from rrls.algorithms import TD3_CPU, algorithm_info, plays_adversary
from rrls.benchmark.grid import Benchmark, RunKey

__all__ = [
    "ENV_STEPS_PER_S",
    "RANDOM_STEPS_PER_S",
    "REPORT_S",
    "STARTUP_S",
    "default_jobs",
    "estimate",
    "format_duration",
    "run_seconds",
    "schedule",
    "size_factor",
    "train_rate",
]

# Training: learning steps per CPU-second of one single-threaded Hopper run: each algorithm's
# row (``rrls.algorithms.AlgorithmInfo.cpu_steps_per_s``, measured by benchmarks/calibrate.py).
# Env steps/s of each task's `env.step`: the evaluation's cost, policy calls excluded.
#: the share of a 256-256 learning step that does not scale with the network (dispatch, autograd
#: nodes, the optimiser's loop, the env step): a step of hidden sizes h costs ``share + (1 -
#: share) * work(h) / work(256-256)`` of a 256-256 one (``size_factor``; calibrated on the
#: quick preset's 64-64 runs against the 256-256 rates above)
FIXED_SHARE = 0.25
RANDOM_STEPS_PER_S = 2_000.0  # warm-up steps (random actions, no update): env, buffer, logging
STARTUP_S = 8.0  # per run: a fresh process importing torch, building envs (4-6 s alone, ~8 s
# with a second run starting beside it: the quick preset's 15 runs, 2 at a time, 2026-11-24)
#: seconds per evaluation step spent in the policy (rrls's exact-order MLP at the lockstep
#: batches an evaluation runs: ~20-60 us a row), on top of the env's own step
POLICY_S_PER_STEP = 30e-6
REPORT_S = 45.0  # once per benchmark: the store, the report and its figures
ENV_STEPS_PER_S = {
    "ant": 3_600.0,
    "halfcheetah": 21_800.0,
    "hopper": 5_600.0,
    "humanoidstandup": 2_100.0,
    "invertedpendulum": 34_000.0,
    "walker": 6_000.0,
}


def estimate(
    spec: Benchmark,
    jobs: int,
    max_episode_steps: int = 1000,
    runs: list[RunKey] | None = None,
    trained: Mapping[RunKey, int] | None = None,
) -> dict[str, float]:
    """Seconds of compute (one core) and wall time with ``jobs`` parallel runs — an estimate
    from measured speeds (±30 %; evaluation episodes counted at full length: an upper bound).
    ``runs``: those to count (default: the whole grid); ``trained``: the steps some have
    trained already (a resumed benchmark's part-trained runs), which they do not train again."""
    train = evals = 0.0
    seconds = []  # each run's, in the order the scheduler starts them
    for key in spec.runs() if runs is None else runs:
        spent, evaluated = run_seconds(spec, key, (trained or {}).get(key, 0), max_episode_steps)
        train, evals = train + spent, evals + evaluated
        seconds.append(spent + evaluated)
    total = train + evals
    return {
        "runs": len(seconds),
        "train_s": train,
        "eval_s": evals,
        "cpu_s": total,
        "wall_s": schedule(seconds, jobs) + REPORT_S,
    }


def train_rate(spec: Benchmark, algo: str) -> float:
    """Learning steps per second of one single-threaded run of ``algo`` at ``spec``'s sizes."""
    info = algorithm_info(algo)
    return (info.cpu_steps_per_s if info else TD3_CPU) / size_factor(spec.hidden)


def run_seconds(
    spec: Benchmark, key: RunKey, trained: int = 0, max_episode_steps: int = 1000
) -> tuple[float, float]:
    """One run's estimated seconds, ``(training, evaluation)``, from ``trained`` steps on."""
    from rrls.envs import get_uncertainty_set

    random_steps = spec.warmup(key.algo)
    done = min(max(trained, 0), spec.steps)
    spent = STARTUP_S + max(random_steps - done, 0) / RANDOM_STEPS_PER_S
    spent += (spec.steps - max(random_steps, done)) / train_rate(spec, key.algo)
    dims = len(get_uncertainty_set(key.task, spec.uncertainty).names)
    env_sps = ENV_STEPS_PER_S.get(key.task, 5_000.0)
    n_periodic = spec.steps // spec.eval_every - done // spec.eval_every if spec.eval_every else 0
    periodic = n_periodic * (spec.eval_episodes + spec.eval_mesh**dims)
    final = spec.mesh**dims * spec.episodes
    dynamic = spec.dynamic_episodes if plays_adversary(key.algo) else 0
    evaluated = (periodic + final + dynamic) * max_episode_steps * (1 / env_sps + POLICY_S_PER_STEP)
    return spent, evaluated


def schedule(seconds: list[float], jobs: int) -> float:
    """When the last of runs lasting ``seconds`` ends, started in that order on ``jobs``
    workers, each run on the first worker free (the local and Ray backends' queue): runs of
    unequal length (RARL's twice TD3's) leave workers idle at the end, and no number of workers
    finishes before the longest run."""
    free = [0.0] * max(1, min(jobs, len(seconds)))
    for run in seconds:
        heapq.heappush(free, heapq.heappop(free) + run)
    return max(free) if seconds else 0.0


def size_factor(hidden: tuple[int, ...]) -> float:
    """A learning step's cost at ``hidden`` relative to the paper's 256-256 (``FIXED_SHARE``)."""

    def work(h: tuple[int, ...]) -> int:  # hidden products, plus ~32 inputs and outputs
        return sum(a * b for a, b in zip(h[:-1], h[1:])) + 32 * (h[0] + h[-1]) if h else 64

    return FIXED_SHARE + (1 - FIXED_SHARE) * work(tuple(hidden)) / work((256, 256))


def default_jobs() -> int:
    from rrls._proc import cores

    return cores()


def format_duration(seconds: float) -> str:
    if seconds < 120:
        return f"{seconds:.0f} s"
    if seconds < 7200:
        return f"{seconds / 60:.0f} min"
    if seconds < 3 * 86400:
        return f"{seconds / 3600:.1f} h"
    return f"{seconds / 86400:.1f} days"
