"""Evaluation engine throughput vs a plain loop and vs the physics bound (issue 3 target).

Side by side in one run, on each task's 3D set (a 5x5x5 mesh by default) with a 256-256 MLP of
fixed random weights, in env steps per second:

(a) plain loop: ``gym.make(...)``, ``set_params``, ``reset(seed)``, ``policy(obs[None])[0]`` per
    step, one episode at a time — with our batch-invariant ``MLPPolicy`` (what the engine's rows
    equal) and with the same MLP called without blocks (the fastest naive loop);
(b) ``rrls.evaluation.evaluate`` with 1 worker and with every core;
(c) the physics bound: ``mj_step(model, data, nstep=frame_skip)`` alone, replaying (a)'s episodes
    (same models, initial states and controls: the same physics), one process, times the cores.

All four run the same episodes: every mesh point, the engine's seed for episode 0.

Physics threads (``--threads 1 2``): the engine with W workers x T threads stepping each worker's
lanes (``rrls.evaluation.kernels.LaneSteps``; ``mj_step`` releases the GIL), and where one
worker's CPU time goes with one thread: the policy, ``mj_step`` (the physics bound's CPU time for
the same steps) and the rest (the Python around them: stepper, observations, rewards, lane
bookkeeping). Threads add cores only where workers leave some idle (on a busy machine they also
take a larger share of it from other processes); the breakdown says what bounds a worker.

Targets: (b, every core) >= 3x (a) and >= 75 % of (c). Each measurement is repeated (``--rounds``)
in alternation and the median is reported.

Scaling (``--workers 1 4 16``, ``--episodes 5 --mesh 10`` for the paper's mesh): for each worker
count W, the engine's rate with its fixed start-up (same call with 1-step episodes: env building,
process start, policy checks) reported apart, and two bounds: one process's physics rate times W
(what the issue's percentages used) and W processes replaying at once (measured: shared cores,
SMT siblings, lower all-core clocks and shared caches count there; both replay episode 0 of each
point: a rate). On a machine whose "cores" are SMT siblings, only the second is reachable. Give
runs long enough that start-up is small: at ``--mesh 8 --episodes 1`` Hopper's random-policy
episodes are ~126 steps, 65 000 env steps in all, about half a second on 16 cores.

    python benchmarks/evaluation.py [--tasks halfcheetah hopper] [--mesh 5] [--rounds 3]
        [--workers 1 2] [--episodes 1] [--threads 1 2]
"""

from __future__ import annotations

import argparse
import os
import statistics
import time
import warnings

import gymnasium as gym
import mujoco
import numpy as np

import rrls  # noqa: F401  (registers the ids)
from rrls.evaluation import MLPPolicy, evaluate, resolve_uncertainty
from rrls.evaluation.engine import run as engine_run
from rrls.evaluation.lanes import (
    LANES,
    Rollouts,
    clear_env_cache,
    episode_seeds,
    make_rollout_envs,
)


def plain_loop(task: str, policy, points: np.ndarray, names, seeds: np.ndarray):
    """Env steps per second of the one-episode-at-a-time loop of the issue, and its actions."""
    env = gym.make(f"rrls/robust-{task}-v0")
    steps, start, episodes = 0, time.perf_counter(), []
    for p, point in enumerate(points):
        params = dict(zip(names, point.tolist()))
        env.set_params(**params)
        obs, _ = env.reset(seed=int(seeds[p, 0]))
        actions = []
        while True:
            action = policy(obs[None])[0]
            actions.append(action)
            obs, _, terminated, truncated, _ = env.step(action)
            if terminated or truncated:
                break
        steps += len(actions)
        episodes.append((params, int(seeds[p, 0]), np.array(actions)))
    return steps / (time.perf_counter() - start), episodes


def physics_bound(task: str, episodes, clock=time.perf_counter) -> float:
    """Raw ``mj_step`` env steps per second (one core), replaying the plain loop's episodes.

    Same initial states, same controls, so exactly the same physics as the engine's rows.
    ``clock``: ``time.process_time`` for CPU seconds (what a busy machine does not inflate).
    """
    from rrls.envs import env_class

    env = env_class(task, "3d")()
    model, data, nstep = env.model, env.data, env.frame_skip
    total, elapsed = 0, 0.0
    for params, seed, actions in episodes:
        env.reset_params()
        env.set_params(**params)
        env.reset(seed=seed)
        start = clock()
        for ctrl in actions:
            data.ctrl[:] = ctrl
            mujoco.mj_step(model, data, nstep=nstep)
        elapsed += clock() - start
        total += len(actions)
    return total / elapsed


def parallel_bound(task: str, episodes, workers: int) -> float:
    """Physics env steps per second of ``workers`` processes replaying at once (sum of rates).

    Each process replays every ``workers``-th episode after a common barrier, so they overlap.
    """
    import multiprocessing as mp

    if workers == 1:
        return physics_bound(task, episodes)
    ctx = mp.get_context("fork")
    barrier, rates = ctx.Barrier(workers), ctx.Queue()

    def replay(w: int) -> None:
        barrier.wait()
        rates.put(physics_bound(task, episodes[w::workers] or episodes[:1]))

    procs = [ctx.Process(target=replay, args=(w,)) for w in range(workers)]
    for proc in procs:
        proc.start()
    total = sum(rates.get() for _ in procs)
    for proc in procs:
        proc.join()
    return total


def engine(
    task: str, policy, mesh: int, episodes: int, workers: int, max_steps: int = 1000
) -> tuple[float, float]:
    """Wall seconds of one ``evaluate`` call and the env steps it ran."""
    start = time.perf_counter()
    result = evaluate(
        policy,
        task,
        "3d",
        mesh=mesh,
        episodes=episodes,
        seed=0,
        workers=workers,
        progress=False,
        max_episode_steps=max_steps,
    )
    return time.perf_counter() - start, int(result.episodes["length"].sum())


def engine_rate(task: str, policy, mesh: int, episodes: int, workers: int) -> float:
    wall, steps = engine(task, policy, mesh, episodes, workers)
    return steps / wall


SHARES = ("policy_share", "physics_share", "rest_share")


def threaded_rate(task: str, policy, mesh: int, workers: int, threads: int) -> float:
    """Env steps per second of ``engine.run`` with ``workers`` processes x ``threads`` threads
    (the same episodes as ``engine``: no policy checks, no result table)."""
    box = resolve_uncertainty(task, "3d")
    points = box.mesh(mesh)
    spec = Rollouts(task, "robust", box.names, points, episode_seeds(0, len(points), 1))
    start = time.perf_counter()
    try:
        cols = engine_run(spec, policy, workers=workers, threads=threads, progress=False)
    finally:
        clear_env_cache()
    return int(cols["length"].sum()) / (time.perf_counter() - start)


def breakdown(task: str, policy, mesh: int, episodes) -> tuple[float, float, float]:
    """One worker in this process, one thread, one BLAS thread: the shares of its CPU time spent
    in the policy, in ``mj_step`` (its steps at the CPU rate of replaying ``episodes``) and in the
    rest (start-up apart). CPU time, so that other processes on the machine do not count."""
    from threadpoolctl import threadpool_limits

    box = resolve_uncertainty(task, "3d")
    points = box.mesh(mesh)
    spec = Rollouts(task, "robust", box.names, points, episode_seeds(0, len(points), 1))
    in_policy = [0.0]

    def timed(obs: np.ndarray) -> np.ndarray:
        start = time.process_time()
        actions = policy(obs)
        in_policy[0] += time.process_time() - start
        return actions

    with threadpool_limits(1):
        try:
            make_rollout_envs(spec, min(LANES, spec.n_episodes))  # building them is start-up
            start = time.process_time()
            cols = engine_run(spec, timed, workers=1, threads=1, progress=False)
            cpu = time.process_time() - start
        finally:
            clear_env_cache()
    physics = int(cols["length"].sum()) / physics_bound(task, episodes, time.process_time) / cpu
    return in_policy[0] / cpu, physics, 1.0 - in_policy[0] / cpu - physics


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--tasks", nargs="+", default=["halfcheetah", "hopper"])
    parser.add_argument("--mesh", type=int, default=5)
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument(
        "--workers", type=int, nargs="+", default=None, help="scaling table (default: 1, cores)"
    )
    parser.add_argument("--episodes", type=int, default=1, help="per mesh point, scaling table")
    parser.add_argument(
        "--threads",
        type=int,
        nargs="+",
        default=[],
        help="physics threads per worker: a table of workers x threads and a time breakdown",
    )
    args = parser.parse_args()
    warnings.simplefilter("ignore")
    cores = len(os.sched_getaffinity(0))
    worker_counts = args.workers or sorted({1, cores})

    rows = []
    for task in args.tasks:
        env = gym.make(f"rrls/robust-{task}-v0")
        policy = MLPPolicy.random(
            env.observation_space.shape[0], env.action_space.shape[0], hidden=(256, 256), seed=0
        )
        naive = policy._forward  # the same MLP, no fixed-size blocks
        box = resolve_uncertainty(task, "3d")
        points = box.mesh(args.mesh)
        seeds = episode_seeds(0, len(points), 1)  # the engine's seeds for episode 0
        runs: dict[str, list[float]] = {k: [] for k in ("plain", "naive", "w1", "w2", "raw")}
        for w in worker_counts:
            runs.update({f"wall{w}": [], f"steps{w}": [], f"start{w}": [], f"par{w}": []})
            runs.update({f"t{w}x{t}": [] for t in args.threads})
        if args.threads:
            runs.update({key: [] for key in SHARES})
        for _ in range(args.rounds):
            rate, episodes = plain_loop(task, policy, points, box.names, seeds)
            runs["plain"].append(rate)
            runs["naive"].append(plain_loop(task, naive, points, box.names, seeds)[0])
            runs["w1"].append(engine_rate(task, policy, args.mesh, 1, 1))
            runs["w2"].append(engine_rate(task, policy, args.mesh, 1, cores))
            runs["raw"].append(physics_bound(task, episodes))
            for w in worker_counts:
                wall, steps = engine(task, policy, args.mesh, args.episodes, w)
                runs[f"wall{w}"].append(wall)
                runs[f"steps{w}"].append(steps)
                runs[f"start{w}"].append(engine(task, policy, args.mesh, args.episodes, w, 1)[0])
                runs[f"par{w}"].append(parallel_bound(task, episodes, w))
                for t in args.threads:
                    runs[f"t{w}x{t}"].append(threaded_rate(task, policy, args.mesh, w, t))
            if args.threads:
                shares = breakdown(task, policy, args.mesh, episodes)
                for key, share in zip(SHARES, shares):
                    runs[key].append(share)
        med = {k: statistics.median(v) for k, v in runs.items()}
        bound = med["raw"] * cores
        rows.append((task, med, bound))

    print(
        f"\nenv steps/s, median of {args.rounds} rounds, {cores} cores, "
        f"mesh {args.mesh}^3 x 1 episode, 256-256 MLP\n"
    )
    print(
        "| task | (a) plain loop | (a') naive MLP loop | (b) engine 1 worker | "
        f"(b) engine {cores} workers | (c) physics bound | (b{cores})/(a) | (b{cores})/(a') | "
        f"(b{cores})/(c) |"
    )
    print("|---|---|---|---|---|---|---|---|---|")
    for task, med, bound in rows:
        print(
            f"| {task} | {med['plain']:,.0f} | {med['naive']:,.0f} | {med['w1']:,.0f} | "
            f"{med['w2']:,.0f} | {bound:,.0f} | {med['w2'] / med['plain']:.2f}x | "
            f"{med['w2'] / med['naive']:.2f}x | {med['w2'] / bound:.0%} |"
        )

    print(
        f"\nscaling: mesh {args.mesh}^3 x {args.episodes} episodes; start-up = the same call "
        "with 1-step episodes; bounds: 1 process x W, and W processes at once\n"
    )
    print(
        "| task | workers | engine steps/s | start-up s | excl. start-up | bound 1xW | "
        "bound W procs | % of 1xW | % of W procs | % of W procs excl. start-up |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|")
    for task, med, _ in rows:
        for w in worker_counts:
            wall, steps, start = med[f"wall{w}"], med[f"steps{w}"], med[f"start{w}"]
            rate, net = steps / wall, steps / max(wall - start, 1e-9)
            naive_bound, par = med["raw"] * w, med[f"par{w}"]
            print(
                f"| {task} | {w} | {rate:,.0f} | {start:.2f} | {net:,.0f} | {naive_bound:,.0f} | "
                f"{par:,.0f} | {rate / naive_bound:.0%} | {rate / par:.0%} | {net / par:.0%} |"
            )

    if args.threads:
        print(
            f"\nphysics threads: engine steps/s, W workers x T threads (mesh {args.mesh}^3 x 1 "
            "episode); one worker's CPU time with one thread (policy / mj_step / the rest)\n"
        )
        cols = [f"{w}x{t}" for w in worker_counts for t in args.threads]
        print(
            "| task | "
            + " | ".join(f"W x T = {c}" for c in cols)
            + " | best / (a) | best / (c) | policy | mj_step | rest |"
        )
        print("|---|" + "---|" * (len(cols) + 5))
        for task, med, bound in rows:
            rates = [med[f"t{c}"] for c in cols]
            print(
                f"| {task} | "
                + " | ".join(f"{r:,.0f}" for r in rates)
                + f" | {max(rates) / med['plain']:.2f}x | {max(rates) / bound:.0%} | "
                + " | ".join(f"{med[k]:.0%}" for k in SHARES)
                + " |"
            )


if __name__ == "__main__":
    main()
