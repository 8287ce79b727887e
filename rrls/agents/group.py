"""What a group of runs trained together is, wherever it trains (``rrls.agents.loop`` for one
algorithm's runs, ``rrls.agents.shared`` for several algorithms' on one twin): the check that
its runs differ only in seed and directory, the memory check before anything is allocated, and
its learner (compiled or not, its state loaded on resume)."""

from __future__ import annotations

import os
from collections.abc import Callable
from contextlib import ExitStack
from pathlib import Path
from typing import Any

import numpy as np
import torch

from rrls.agents import graphs
from rrls.agents.config import TrainConfig
from rrls.agents.hparams import check_memory
from rrls.agents.learner import stack_runs
from rrls.agents.lookup import Algorithm, ResolvedRun, warm_up
from rrls.agents.run import Run
from rrls.agents.streams import RunSeeds
from rrls.agents.threads import process_settings
from rrls.files import DirectoryLock

#: ``train(runs, states, members, threads)``: train ``members`` (indices of ``runs``, all at
#: one step) from their checkpoints ``states`` (None: a fresh start)
TrainAtStep = Callable[[list[Run], dict[int, Any], list[int], Any], None]


def run_groups(resolved: list[ResolvedRun], resume: bool, train: TrainAtStep) -> list[Path]:
    """The runs' directories locked (a second command writing one is refused) and opened
    (resumed or fresh), the unfinished ones trained by ``train`` in groups of equal step (runs
    resumed from different steps continue apart), the runs closed whatever happens; their
    directories."""
    with ExitStack() as locks:
        for r in resolved:
            if r.settings.out is not None:
                locks.enter_context(DirectoryLock(r.settings.out))
        runs = [Run(r.settings, resume, r.hyper) for r in resolved]
        try:
            pending = [k for k, run in enumerate(runs) if not run.finished]
            states = {k: runs[k].load() for k in pending}
            by_step: dict[int, list[int]] = {}
            for k in pending:
                by_step.setdefault(runs[k].step, []).append(k)
            for step in sorted(by_step):
                with process_settings(resolved[0].settings.threads) as threads:
                    train(runs, states, by_step[step], threads)
        finally:
            for run in reversed(runs):
                run.close()
    return [run.dir for run in runs]


def check_group(resolved: list[ResolvedRun]) -> None:
    """The runs of a group must differ only in seed and directory."""
    configs = [r.settings for r in resolved]
    first, reference = configs[0], configs[0].identity(resolved[0].hyper)
    same = ("steps", "device", "eval_every", "eval_episodes", "eval_mesh", "checkpoint_every")
    for config, run in zip(configs[1:], resolved[1:]):
        identity = config.identity(run.hyper)
        diff = [k for k, v in reference.items() if k != "seed" and identity[k] != v]
        diff += [name for name in same if getattr(config, name) != getattr(first, name)]
        if diff:
            raise ValueError(
                f"runs trained together must differ only in seed and out; these differ: "
                f"{', '.join(sorted(set(diff)))}"
            )
    # realpath: Path.resolve raises RuntimeError on a loop of links (Python 3.11); the run's
    # directory refuses it in one line when it is made
    outs = [os.path.realpath(c.out) for c in configs]
    if len(set(outs)) != len(outs):
        raise ValueError("runs trained together need one directory each (--out)")


def check_group_memory(hyper: Any, env: Any, group: int, steps: int) -> None:
    """Refuse, before the learner allocates them, replay buffers and networks that cannot fit
    in this machine's memory (float32 transitions of ``min(buffer_size, steps)`` rows per run;
    each network with its target, gradient and two Adam moments)."""
    size = {k: int(np.prod(s.shape)) for k, s in _spaces(env).items()}
    obs, act = size.get("obs", 0), size.get("act", 0)
    rows = min(int(getattr(hyper, "buffer_size", 0) or 0), max(steps, 0))
    replay = rows * (2 * obs + act + 2) * 4
    hidden = list(getattr(hyper, "hidden", ()) or ())
    params = 0
    for sizes in ([obs, *hidden, act], [obs + act, *hidden, 1], [obs + act, *hidden, 1]):
        params += sum(a * b + b for a, b in zip(sizes[:-1], sizes[1:]))
    check_memory(
        group * (replay + 5 * 4 * params),
        f"{group} run(s) with {rows:,} replay transitions and {hidden} networks each",
        "lower --buffer-size or --hidden, or train fewer runs together",
    )


def _spaces(env: Any) -> dict[str, Any]:
    out = {}
    for key, space in (("obs", env.observation_space), ("act", env.action_space)):
        if getattr(space, "shape", None) is not None:
            out[key] = space
    return out


#: updates left below which ``--compile``'s default is off: compiling (~35 s the first time on a
#: machine, ~4 s from the cache) is not paid back by a short run or a test
COMPILE_MIN_UPDATES = 20_000
#: devices where the default compiles (with enough updates left). Not the CPU: measured on a
#: 2-core AMD EPYC (torch 2.13, Hopper TD3, 256-256, batch 256, 1 thread), a compiled update
#: costs as much CPU time as an eager one (6.5-7.0 ms against 5.9-6.8 ms): the GEMMs are ~80 %
#: of it and the compiled graphs' own overhead (a dozen frames per update, split by
#: ``backward`` and ``Optimizer.step``'s graph breaks) eats what fusion saves
COMPILE_PAYS_ON = ("cuda",)


def compiles(config: TrainConfig, learning_starts: int, step: int) -> bool:
    """``--compile``, or by default: on a device of ``COMPILE_PAYS_ON``, whether the updates
    left from ``step`` are ``COMPILE_MIN_UPDATES`` or more."""
    if config.compile is not None:
        return config.compile
    if torch.device(config.device).type not in COMPILE_PAYS_ON:
        return False
    return config.steps - max(step, learning_starts) >= COMPILE_MIN_UPDATES


def build_learner(
    algo: Algorithm, hyper: Any, runs: list[Run], states: list[dict[str, Any] | None], template: Any
) -> Any:
    """The group's learner for ``template``'s spaces, compiled or not (``compiles``), its state
    loaded from the runs' checkpoints on resume."""
    first = runs[0].config
    # the learner's updates read these when made; a learner made elsewhere keeps the defaults
    compiled = compiles(first, warm_up(hyper), runs[0].step)
    with graphs.settings(graphs=first.cuda_graphs, compile=compiled):
        streams = [RunSeeds(run.config.seed) for run in runs]
        learner = algo.Learner(template, hyper, streams, torch.device(first.device))
    if any(state is not None for state in states):
        learner.load_state_dict(stack_runs([state["learner"] for state in states]))
    return learner


__all__ = [
    "COMPILE_MIN_UPDATES",
    "COMPILE_PAYS_ON",
    "build_learner",
    "check_group",
    "check_group_memory",
    "compiles",
    "run_groups",
]
