"""Training speed of groups of runs: K runs in one process (``train_group``) against K
processes, on a CPU or a GPU: the ``--groups`` section of ``benchmarks/train_speed.py``, which
parses the options and calls ``groups`` here.

For each ``--ks`` K (default 1 8 32), ``--algos`` (default td3) and ``--device`` (cpu; cuda rows
are skipped with a note where no GPU is present), side by side, each measurement a fresh process:

(a) CleanRL's TD3 loop (``cleanrl_loops.cleanrl``; CPU: the reference for every row);
(b) K runs in one process (``rrls.agents.loop.train_group``, seeds 0..K-1, default threads; a
    non-daemonic worker, so a GPU group of 16 or more can start its env workers):
    aggregated env steps/s (K per loop step), per run, and against (a);
(c) K separate processes started together, ``--threads 1`` each: aggregated env steps/s. All
    K wait at a barrier once their warm-up is done, so their timed windows overlap, and each
    keeps stepping for half as many steps again after its window so the load stays K processes
    until the slowest has finished; ``--process-steps`` (default 100) timed steps each, fewer
    than (b)'s: K processes on 2 cores each get 2/K of a core, and the rate over a window only
    needs the window to be shared by all K.
(b)/(c) is the CPU target (issue: >= 1.0, no slower per run than separate processes); GPU
targets (H100): K=1 TD3 >= 2 000 steps/s, K=32 TD3 >= 20 000 aggregated, M2TD3 K=32 >= 10 000
(measured on one: docs/results/gpu/h100-2026-11-25.md).

Steps/s are *after learning starts*: each loop step is time-stamped where the loop calls
``envs.step`` (``rrls.agents.loop.make_envs`` wrapped, so envs in worker processes are timed
too) and the rate is taken between the stamps of loop steps ``learning_starts + group_warmup``
and ``+ group_steps``, so the random warm-up, the first updates, process start-up and the final
export are all outside the window.
"""

from __future__ import annotations

import argparse
import importlib.util
import multiprocessing
import os
import queue
import statistics
import tempfile
import time
import warnings
from concurrent.futures import ProcessPoolExecutor
from typing import Any

import torch
from cleanrl_loops import cleanrl

from rrls.agents import TrainConfig
from rrls.agents.loop import train_group


def _cleanrl(task: str, steps: int, warmup: int) -> float:
    warnings.simplefilter("ignore")
    return cleanrl(task, steps, warmup)


def timed_config(
    algo: str,
    task: str,
    steps: int,
    out: str,
    learning_starts: int,
    threads: int | None,
    compile: bool | None,
    **extra: Any,
) -> TrainConfig:
    """A timed run's config (here and in ``train_speed.py``): the 3D set, no periodic
    evaluation, checkpoint or progress bar inside the window."""
    return TrainConfig(
        algo=algo,
        task=task,
        uncertainty="3d",
        steps=steps,
        eval_every=0,
        out=out,
        progress=False,
        checkpoint_every=10**9,
        threads=threads,
        compile=compile,
        hyper={"learning_starts": learning_starts},
        **extra,
    )


def rrls_group(
    algo: str,
    task: str,
    k: int,
    steps: int,
    warmup: int,
    learning_starts: int = 1000,
    threads: int | None = None,
    device: str = "cpu",
    barrier: Any = None,
    tail: int = 0,
    compile: bool | None = None,
) -> float:
    """Aggregated env steps/s of ``k`` runs trained together (``train_group``), after learning
    starts: between the env-step stamps of loop steps ``learning_starts + warmup`` and
    ``+ steps``. ``barrier`` (separate processes) is waited on just before the window opens, so
    concurrent processes time the same stretch; ``tail`` more steps follow the window (load).
    ``compile``: ``--compile`` (``None``: the default, off for runs this short)."""
    from rrls.agents import loop

    first = learning_starts + warmup
    stamps: list[float] = []  # one per loop step (k env steps), taken where the loop steps
    plain = loop.make_envs  # the group's envs, in this process or in env workers

    def clocked(*args: Any, **kwargs: Any) -> Any:
        envs = plain(*args, **kwargs)
        step = envs.step

        def stamped(actions: list[Any]) -> list[tuple]:
            if barrier is not None and len(stamps) == first:
                barrier.wait(timeout=3600)
            stamps.append(time.perf_counter())
            return step(actions)

        envs.step = stamped
        return envs

    loop.make_envs = clocked
    try:
        with tempfile.TemporaryDirectory() as out:
            configs = [
                timed_config(
                    algo,
                    task,
                    first + steps + tail + 1,
                    f"{out}/seed{seed}",
                    learning_starts,
                    threads,
                    compile,
                    seed=seed,
                    device=device,
                )
                for seed in range(k)
            ]
            train_group(configs)
    finally:
        loop.make_envs = plain
    return k * steps / (stamps[first + steps] - stamps[first])


def _group_job(args: tuple) -> float:
    warnings.simplefilter("ignore")
    return rrls_group(*args)


def _process_job(args: tuple, barrier: Any, results: Any) -> None:
    warnings.simplefilter("ignore")
    try:
        results.put(rrls_group(*args))
    except BaseException as err:  # noqa: BLE001 - the parent reports it
        barrier.abort()
        results.put(err)


def separate_processes(
    algo: str, task: str, k: int, steps: int, warmup: int, learning_starts: int, device: str
) -> float:
    """Summed env steps/s of ``k`` single-threaded processes (one run each) started together;
    their timed windows coincide (a barrier) and each keeps going ``steps // 2`` steps after
    its window, so every window is shared by all ``k`` processes."""
    ctx = multiprocessing.get_context("spawn")
    barrier, results = ctx.Barrier(k), ctx.Queue()
    job = (algo, task, 1, steps, warmup, learning_starts, 1, device)
    procs = [
        ctx.Process(target=_process_job, args=((*job, None, steps // 2), barrier, results))
        for _ in range(k)
    ]
    for proc in procs:
        proc.start()
    rates: list[Any] = []
    while len(rates) < k:
        try:
            rates.append(results.get(timeout=5))
        except queue.Empty:  # a process killed outright (out of memory) reports nothing
            if any(p.exitcode not in (None, 0) for p in procs):
                barrier.abort()
                for proc in procs:
                    proc.terminate()
                raise RuntimeError(f"a process of the K={k} row died (out of memory?)") from None
    for proc in procs:
        proc.join()
    errors = [r for r in rates if isinstance(r, BaseException)]
    if errors:
        raise RuntimeError(f"{len(errors)} of {k} processes failed: {errors[0]!r}")
    return sum(rates)


def machine() -> str:
    """One line naming the CPU (and GPU) the table was measured on."""
    from rrls.provenance import machine as cpu

    model = cpu()["cpu"]
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    gpu = torch.cuda.get_device_name(0) if torch.cuda.is_available() else "no GPU"
    return f"{model}, {cores} cores, {gpu}; torch {torch.__version__}"


def groups(args: argparse.Namespace) -> None:
    """The K-rows table: (a) CleanRL's loop, (b) ``train_group``, (c) K processes; (a) is
    re-measured here with the section's window, so every row shares one warm-up and length."""
    devices = []
    for device in args.device:
        if device == "cuda" and not torch.cuda.is_available():
            print("no CUDA device: the cuda rows are skipped (built and tested on CPU only)")
            continue
        devices.append(device)
    ctx = multiprocessing.get_context("spawn")
    reference = None
    if importlib.util.find_spec("stable_baselines3") is not None:
        with ctx.Pool(1, maxtasksperchild=1) as pool:
            ref = [
                pool.apply(_cleanrl, (args.task, args.group_steps, args.group_warmup))
                for _ in range(args.group_rounds)
            ]
        reference = statistics.median(ref)
    print(
        f"\nGroups of runs, {args.task}, one update per env step per run, steps/s after "
        f"learning starts ({args.learning_starts} random steps, then {args.group_warmup} "
        f"updates; (b) {args.group_steps} timed steps, (c) {args.process_steps}), median of "
        f"{args.group_rounds} round(s). Machine: {machine()}.\n"
    )
    if reference is not None:
        print(
            f"(a) CleanRL's loop (CPU, TD3, one run, its own 1 000 random steps): "
            f"{reference:.0f} steps/s\n"
        )
    else:
        print("(a) CleanRL's loop skipped: stable-baselines3 is not installed\n")
    print(
        "| device | algo | K | (b) K runs in one process: env steps/s | per run | (b) / (a) "
        "| (c) K processes, 1 thread each: env steps/s | (b)/(c) |"
    )
    print("|---|---|---|---|---|---|---|---|", flush=True)
    # each row printed as soon as its rounds are done: a run cut short (a GPU lease) keeps them
    for device in devices:
        for algo in args.algos:
            for k in args.ks:
                together, apart = [], []
                job = (algo, args.task, k, args.group_steps, args.group_warmup)
                for _ in range(args.group_rounds):
                    # not a Pool: its daemonic worker could not start the group's env workers
                    with ProcessPoolExecutor(1, mp_context=ctx) as pool:
                        whole = (*job, args.learning_starts, None, device)
                        together.append(pool.submit(_group_job, whole).result())
                    apart.append(
                        separate_processes(
                            algo,
                            args.task,
                            k,
                            args.process_steps,
                            args.group_warmup,
                            args.learning_starts,
                            device,
                        )
                    )
                b, c = statistics.median(together), statistics.median(apart)
                vs_a = f"{b / reference:.2f}x" if reference else "-"
                print(
                    f"| {device} | {algo} | {k} | {b:.0f} | {b / k:.0f} | {vs_a} | {c:.0f} "
                    f"| {b / c:.2f}x |",
                    flush=True,
                )
    print(
        "\nTargets: CPU (b)/(c) >= 1.0 (no slower per run than separate processes); on an H100 "
        "TD3 K=1 >= 2 000, TD3 K=32 >= 20 000, M2TD3 K=32 >= 10 000 env steps/s (b)."
    )
