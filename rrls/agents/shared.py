"""Several algorithms' runs of one task trained on one MuJoCo Warp twin: ``train_group`` given
runs of more than one algorithm (``rrls benchmark --simulator warp`` packs a task's runs so).

A twin step costs about the same for tens of worlds as for hundreds (``docs/twin.md``), so the
protocol's runs pay on a GPU only when they share steps. Each algorithm's runs take consecutive
worlds in its mode (``WarpTwin(modes=...)``), its own learner (one batched update for its runs)
and its own driver with its run directories; one twin step moves them all
(``rrls.agents.resident.SharedBlocks``), the drivers in lockstep
(``rrls.agents.driver.drive``). A run's numbers are those it has trained with its algorithm
alone (``tests/test_twin_shared.py``); runs resumed at different steps continue in groups of
equal step.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import torch

from rrls.agents import resident
from rrls.agents.driver import Driver, drive
from rrls.agents.envs import env_factory
from rrls.agents.group import build_learner, check_group, check_group_memory, run_groups
from rrls.agents.lookup import ResolvedRun, warm_up
from rrls.agents.run import Run

#: what the runs sharing a twin must agree on (they step and stop together)
SHARED = (
    "task",
    "uncertainty",
    "steps",
    "device",
    "simulator",
    "max_episode_steps",
    "eval_every",
    "eval_episodes",
    "eval_mesh",
    "checkpoint_every",
    "threads",
    "split",
)


def check_shared(resolved: list[ResolvedRun]) -> None:
    """Runs of several algorithms share a twin only on ``--simulator warp``, every algorithm's
    learner device-resident, the rest of their settings alike (``SHARED``); within an
    algorithm, runs differ only in seed and directory (``check_group``)."""
    first = resolved[0].settings
    diff = [n for n in SHARED for r in resolved if getattr(r.settings, n) != getattr(first, n)]
    if diff:
        raise ValueError(
            "runs of several algorithms train together on one twin with the same "
            f"{', '.join(SHARED)}; these differ: {', '.join(sorted(set(diff)))}"
        )
    for r in resolved:
        if not resident.trains_on_device(r.settings, r.algorithm.Learner, r.hyper):
            raise ValueError(
                f"runs of several algorithms train together only on the Warp twin, each "
                f"device-resident (--simulator warp); {r.settings.algo} here is not"
            )
    for ks in _by_algo(resolved, range(len(resolved))).values():
        check_group([resolved[k] for k in ks])


def train_shared(
    resolved: list[ResolvedRun],
    resume: bool = False,
    on_episode: Callable[[int, int, float], None] | None = None,
) -> list[Path]:
    """Train ``resolved`` (runs of several algorithms of one task) on one twin; their
    directories. ``on_episode(k, step, return)`` as ``train_group``'s."""
    check_shared(resolved)

    def train_at(runs: list[Run], states: dict[int, Any], members: list[int], threads: Any):
        _together(resolved, runs, states, members, on_episode, threads)

    return run_groups(resolved, resume, train_at)


def _by_algo(resolved: list[ResolvedRun], members: Any) -> dict[str, list[int]]:
    out: dict[str, list[int]] = {}
    for k in members:
        out.setdefault(resolved[k].settings.algo, []).append(k)
    return out


def _together(
    resolved: list[ResolvedRun],
    runs: list[Run],
    states: dict[int, dict[str, Any] | None],
    members: list[int],
    on_episode: Callable[[int, int, float], None] | None,
    threads: Any,
) -> None:
    """``members`` (at one step) on one twin: each algorithm's learner, part and driver."""
    first = runs[members[0]].config
    by_algo = _by_algo(resolved, members)
    groups = [
        (algo, [runs[k].config.seed for k in ks], resolved[ks[0]].hyper)
        for algo, ks in by_algo.items()
    ]
    twin = resident.make_shared_twin(
        first.task,
        groups,
        first.training_set(),
        first.device,
        max_episode_steps=first.max_episode_steps,
    )
    device = torch.device(first.device)
    try:
        parts, made, lo = [], [], 0
        for algo, ks in by_algo.items():
            group = resolved[ks[0]]
            mine = [runs[k] for k in ks]
            template = env_factory(group.algorithm, mine[0].config, group.hyper)()
            try:
                check_group_memory(group.hyper, template, len(ks), first.steps - mine[0].step)
                learner = build_learner(
                    group.algorithm, group.hyper, mine, [states[k] for k in ks], template
                )
                metas = [run.metadata(template) for run in mine]
            finally:
                template.close()
            seeds = [run.config.seed for run in mine]
            parts.append(resident.make_part(twin, learner, seeds, warm_up(group.hyper), algo, lo))
            made.append((ks, mine, metas))
            lo += len(ks)
        shared = resident.SharedBlocks(twin, parts, device)
        drivers = []
        for part, (ks, mine, metas), collector in zip(parts, made, shared.collectors()):
            hook = None
            if on_episode is not None:
                hook = (lambda keys: lambda i, s, r: on_episode(keys[i], s, r))(ks)
            drivers.append(
                Driver(
                    part.learner,
                    collector,
                    group=len(ks),
                    steps=first.steps,
                    starts=part.starts,
                    runs=mine,
                    metas=metas,
                    step=mine[0].step,
                    on_episode=hook,
                    threads=threads,
                )
            )
        drive(drivers, [[states[k] for k in ks] for ks, _, _ in made])
    finally:
        twin.close()


__all__ = ["SHARED", "check_shared", "train_shared"]
