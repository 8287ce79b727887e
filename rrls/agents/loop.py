"""The entry points of training (``train``, ``train_group``): every algorithm runs here, bringing
only its ``Learner`` (``rrls.agents.learner``: act, observe, update, state_dict,
load_state_dict, export).

What is set up here, once per group of runs: the runs' directories (locked, resumed or fresh:
``rrls.agents.run``), the group's check (runs differ only in seed and directory), resumed runs
grouped by step, the process's threads, the envs (CPU envs in this process or in workers, or
the MuJoCo Warp twin with ``--simulator warp``), the memory check and the learner (compiled or
not, its state loaded on resume). Then one driver (``rrls.agents.driver``) owns the run's
cadence, whichever collector steps the envs: ``rrls.agents.stepwise`` (CPU envs, and the
twin's envs for learners without the device methods) or ``rrls.agents.resident`` (the twin's
device-resident blocks).

Every generator of a run is a child of ``SeedSequence(seed)`` (``rrls.agents.streams``): the
collectors' ``"env"`` (first reset) and ``"warmup"`` streams, the learner's own.
"""

from __future__ import annotations

import multiprocessing
import signal
from collections.abc import Callable
from pathlib import Path
from typing import Any

import torch

from rrls.agents import resident
from rrls.agents.boundary import ctrl_c_signals
from rrls.agents.config import TrainConfig
from rrls.agents.driver import Collector, Driver
from rrls.agents.envs import env_factory, make_envs
from rrls.agents.group import build_learner, check_group, check_group_memory, run_groups
from rrls.agents.lookup import Algorithm, ResolvedRun, resolve_run, warm_up
from rrls.agents.run import Run
from rrls.agents.stepwise import StepCollector, uniform


def train(
    config: TrainConfig,
    resume: bool = False,
    on_episode: Callable[[int, float], None] | None = None,
) -> Path:
    """Train ``config.algo`` on ``config.task``; returns the run directory.

    With ``resume``, a checkpoint in ``config.out`` is continued exactly (no checkpoint: a fresh
    start; a finished run with as many steps: returned as it is). ``on_episode(step, return)``
    is called at every episode end (progress displays of a driver running many runs).
    """
    hook = None if on_episode is None else (lambda k, step, ret: on_episode(step, ret))
    return train_group([config], resume, hook)[0]


def train_group(
    configs: list[TrainConfig],
    resume: bool = False,
    on_episode: Callable[[int, int, float], None] | None = None,
) -> list[Path]:
    """Train several runs of one algorithm on one task together; returns their directories
    (runs of several algorithms on one MuJoCo Warp twin: ``rrls.agents.shared``).

    The runs (typically different seeds) differ only in ``seed`` and ``out``; one learner holds
    them all (one batched update) and their envs step in lockstep. Each run keeps its own
    directory, checkpoint, logs and policy; its numbers equal those it has alone up to float32
    rounding (``tests/test_group.py``), and bit for bit given the same group. Resumed runs that
    stopped at different steps are continued in groups of equal step.
    """
    if not configs:
        return []
    resolved = [resolve_run(c) for c in configs]  # each run's algorithm and Config, once
    if len({r.settings.algo for r in resolved}) > 1:  # several algorithms: one twin step
        from rrls.agents.shared import train_shared

        return train_shared(resolved, resume, on_episode)
    check_group(resolved)
    group = resolved[0]  # the runs differ only in seed and directory

    def train_at(runs: list[Run], states: dict[int, Any], members: list[int], threads: Any):
        hook = None
        if on_episode is not None:
            hook = (lambda ks: lambda i, s, r: on_episode(ks[i], s, r))(members)
        group_runs, group_states = [runs[k] for k in members], [states[k] for k in members]
        _train_together(group, group_runs, group_states, hook, threads)

    return run_groups(resolved, resume, train_at)


def _train_together(group: ResolvedRun, runs, states, on_episode, threads) -> None:
    """One group of runs at the same step: its envs, then its learner and driver."""
    first, algo, hyper = runs[0].config, group.algorithm, group.hyper
    make = env_factory(algo, first, hyper)
    template = make()  # spaces and metadata; the group's envs may live in worker processes
    check_group_memory(hyper, template, len(runs), first.steps - runs[0].step)
    if resident.trains_on_device(first, algo.Learner, hyper):  # the twin, never leaving the device
        seeds = [run.config.seed for run in runs]
        envs: Any = resident.make_twin(
            first.task,
            first.algo,
            seeds,
            first.training_set(),
            first.device,
            hyper,
            max_episode_steps=first.max_episode_steps,
        )
    elif first.simulator == "warp":  # the twin, each episode begun on the run's CPU env
        from rrls.agents.twin_envs import TwinEnvs

        envs = TwinEnvs(make, len(runs), first.task, first.training_set(), first.device)
    else:
        envs = _without_ctrl_c(make_envs, make, len(runs), env_workers(first, len(runs)))
    try:
        _collect(algo, hyper, runs, states, on_episode, threads, template, envs)
    finally:
        envs.close()


def _without_ctrl_c(start: Callable[..., Any], *args: Any) -> Any:
    """``start(*args)`` with Ctrl-C (and SIGTERM where it is Ctrl-C) ignored while it starts
    processes, which inherit that: the terminal's Ctrl-C reaches the whole process group (a
    scheduler's SIGTERM every process of the job), and an env worker it killed would leave the
    loop unable to finish the step whose end the checkpoint at Ctrl-C keeps. The workers die
    with the loop's process all the same."""
    previous = {sig: signal.signal(sig, signal.SIG_IGN) for sig in ctrl_c_signals()}
    try:
        return start(*args)
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)


def env_workers(config: TrainConfig, group: int) -> int:
    """``--env-workers``, or by default: none on a CPU (the update dominates), on a GPU one per
    4 envs of a group of 16 or more, within the cores. Measured on an H100 machine's 16-core
    Xeon (2026-11-25, docs/results/gpu): a loop step of 32 Hopper envs, resets included, took
    5.1 ms in-process, 3.0 ms with 4 workers, 2.05 with 8, 1.83 with 15; 8 envs took 1.1 ms
    in-process and 2.0 with one worker (the pipe costs more than it saves)."""
    if config.env_workers is not None:
        return config.env_workers
    if not config.device.startswith("cuda") or group < 16:
        return 0
    if multiprocessing.current_process().daemon:  # a Pool worker: it may not have children
        return 0
    from rrls._proc import cores

    return max(0, min(group // 4, cores() - 1))


def _collect(
    algo: Algorithm,
    hyper: Any,
    runs: list[Run],
    states: list[dict[str, Any] | None],
    on_episode: Callable[[int, int, float], None] | None,
    threads: Any,
    template: Any,
    envs: Any,
) -> None:
    """Build the group's learner (its state loaded on resume) and drive its collector."""
    first = runs[0].config
    seeds = [run.config.seed for run in runs]
    learning_starts = warm_up(hyper)
    learner = build_learner(algo, hyper, runs, states, template)
    collector: Collector
    if resident.trains_on_device(first, algo.Learner, hyper):
        device = torch.device(first.device)
        collector = resident.BlockCollector.alone(
            envs, learner, seeds, learning_starts, first.algo, device
        )
    else:
        paths = [run.checkpoint_path for run in runs]
        collector = StepCollector(
            envs,
            learner,
            template.action_space,
            seeds,
            learning_starts,
            first.max_episode_steps,
            paths,
            first.algo,
        )
    driver = Driver(
        learner,
        collector,
        group=len(runs),
        steps=first.steps,
        starts=learning_starts,
        runs=runs,
        metas=[run.metadata(template) for run in runs],
        step=runs[0].step,
        on_episode=on_episode,
        threads=threads,
    )
    driver.run(states)


__all__ = [
    "env_workers",
    "make_envs",
    "train",
    "train_group",
    "uniform",
]
