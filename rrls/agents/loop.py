"""The one collection loop every algorithm runs: an algorithm only brings its ``Learner``
(``rrls.agents.learner``: act, observe, update, state_dict, load_state_dict, export).

The loop owns what algorithms share, written once: the environments and their seeding, the
uniformly random warm-up, acting, time limits (an episode truncated at ``max_episode_steps``
bootstraps, a terminated one does not, and no transition crosses a reset), when updates start,
periodic evaluation, checkpoints (each run's slice of the learner's state, taken every
``checkpoint_every`` steps and at Ctrl-C, at the end of the step it came in, mid-episode: the
episode in progress is replayed on resume, so the resumed run continues bit for bit), logs and
the export of the final policies.

Every generator of a run is a child of ``SeedSequence(seed)`` (``rrls.agents.streams``): the
loop's ``"env"`` (first reset) and ``"warmup"`` streams, the learner's own.

On the MuJoCo Warp twin (``--simulator warp``), a learner with the device-resident methods runs
``rrls.agents.resident``'s blocks of steps instead of this step-by-step loop (the rest, the
run's files, checkpoints, logs and evaluations, is shared).
"""

from __future__ import annotations

import json
import multiprocessing
import os
import signal
from collections.abc import Callable
from contextlib import ExitStack
from pathlib import Path
from typing import Any

import numpy as np
import torch

from rrls._io import DirectoryLock
from rrls.agents import graphs, resident
from rrls.agents.config import Diverged, TrainConfig
from rrls.agents.envs import env_factory, make_envs
from rrls.agents.hparams import check_memory
from rrls.agents.learner import check_runs_first, run_slice, stack_runs
from rrls.agents.lookup import Algorithm, ResolvedRun, resolve_run
from rrls.agents.run import Run, StepBoundary, active_ctrl_c, export_policies
from rrls.agents.streams import RunSeeds, rng_state, set_rng_state
from rrls.agents.threads import process_settings
from rrls.schema import loads_json


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
    """Train several runs of one algorithm on one task together; returns their directories.

    The runs (typically different seeds) differ only in ``seed`` and ``out``; one learner holds
    them all (one batched update) and their envs step in lockstep. Each run keeps its own
    directory, checkpoint, logs and policy; its numbers equal those it has alone up to float32
    rounding (``tests/test_group.py``), and bit for bit given the same group. Resumed runs that
    stopped at different steps are continued in groups of equal step.
    """
    if not configs:
        return []
    resolved = [resolve_run(c) for c in configs]  # each run's algorithm and Config, once
    _check_group(resolved)
    with ExitStack() as locks:  # a second command writing the same run directory is refused
        for c in configs:
            if c.out is not None:
                locks.enter_context(DirectoryLock(c.out))
        return _train_runs(resolved, resume, on_episode)


def _train_runs(resolved: list[ResolvedRun], resume, on_episode) -> list[Path]:
    group = resolved[0]  # the runs differ only in seed and directory (_check_group)
    runs = [Run(r.settings, resume, group.hyper) for r in resolved]
    try:
        pending = [k for k, run in enumerate(runs) if not run.finished]
        states = {k: runs[k].load() for k in pending}
        by_step: dict[int, list[int]] = {}
        for k in pending:
            by_step.setdefault(runs[k].step, []).append(k)
        for step in sorted(by_step):
            members = by_step[step]
            hook = None
            if on_episode is not None:
                hook = (lambda ks: lambda i, s, r: on_episode(ks[i], s, r))(members)
            with process_settings(group.settings.threads) as threads:
                _train_together(
                    group, [runs[k] for k in members], [states[k] for k in members], hook, threads
                )
    finally:
        for run in reversed(runs):
            run.close()
    return [run.dir for run in runs]


def _check_group(resolved: list[ResolvedRun]) -> None:
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


class _Episode:
    """How run ``k``'s current episode began and what it did: a checkpoint taken mid-episode
    replays it (same generator, same reset, same actions: the same physics) on resume."""

    def __init__(self, env_rng: str, seed: int | None, options: dict | None) -> None:
        self.env_rng, self.seed, self.options = env_rng, seed, options
        self.actions: list[Any] = []
        self.ret, self.length = 0.0, 0

    def state(self, obs: np.ndarray) -> dict[str, Any]:
        parts: list[torch.Tensor] = []
        tuples = bool(self.actions) and isinstance(self.actions[0], tuple)
        if self.actions:
            columns = zip(*self.actions) if tuples else [self.actions]
            parts = [torch.as_tensor(np.stack(c)) for c in columns]
        return {
            "env_rng": self.env_rng,
            "seed": self.seed,
            "options": json.dumps(self.options),
            "tuple": tuples,
            "actions": parts,
            "obs": torch.as_tensor(np.asarray(obs)),
        }


def _begin(envs: Any, k: int, seed: int | None, options: dict | None) -> tuple:
    state, obs = envs.begin(k, seed, options)  # one round trip to an env worker, not two
    return obs, _Episode(state, seed, options)


def _options(saved: dict[str, Any], path: Path) -> Any:
    """The reset options of the episode a checkpoint was taken in (JSON in the checkpoint)."""
    return loads_json(saved["options"], f"{path}: the episode's reset options")


def _replay(envs: Any, k: int, saved: dict[str, Any], path: Path) -> tuple:
    """Re-run the episode a checkpoint was taken in, up to the checkpoint."""
    envs.set_rng_state(k, saved["env_rng"])
    obs, episode = _begin(envs, k, saved["seed"], _options(saved, path))
    parts = [p.numpy() for p in saved["actions"]]
    for i in range(len(parts[0]) if parts else 0):
        action = tuple(p[i] for p in parts) if saved["tuple"] else parts[0][i]
        obs, reward, *_ = envs.step_one(k, action)
        episode.actions.append(action)
        episode.ret += reward
        episode.length += 1
    if not np.array_equal(obs, saved["obs"].numpy()):
        raise RuntimeError(
            f"cannot resume from {path}: replaying the episode in progress did not reproduce "
            "its state (the physics differs from the machine that wrote the checkpoint)"
        )
    return obs, episode


def _train_together(group: ResolvedRun, runs, states, on_episode, threads) -> None:
    """The collection loop of one group of runs at the same step."""
    first, algo, hyper = runs[0].config, group.algorithm, group.hyper
    make = env_factory(algo, first, hyper)
    template = make()  # spaces and metadata; the group's envs may live in worker processes
    check_group_memory(hyper, template, len(runs), first.steps - runs[0].step)
    if resident.trains_on_device(first, algo.Learner):  # the twin, without leaving the device
        envs: Any = resident.make_twin(first, [run.config.seed for run in runs])
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
    """``start(*args)`` with Ctrl-C ignored while it starts processes, which inherit that: the
    terminal's Ctrl-C reaches the whole process group, and an env worker it killed would leave
    the loop unable to finish the step whose end the checkpoint at Ctrl-C keeps."""
    if not active_ctrl_c():
        return start(*args)
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        return start(*args)
    finally:
        signal.signal(signal.SIGINT, previous)


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


def uniform(space: Any, rng: np.random.Generator) -> Any:
    """A uniformly random action of a ``Box`` (or of each ``Box`` of a ``Tuple``) space."""
    if hasattr(space, "spaces"):
        return tuple(uniform(s, rng) for s in space.spaces)
    return rng.uniform(space.low, space.high).astype(np.float32)


def _collect(
    algo: Algorithm,
    hyper,
    runs,
    states,
    on_episode,
    threads,
    template,
    envs,
) -> None:
    first = runs[0].config
    seeds = [RunSeeds(run.config.seed) for run in runs]
    warmup = [s.numpy("warmup") for s in seeds]
    learning_starts = int(getattr(hyper, "learning_starts", 0))
    # the learner's updates read these when made; a learner made elsewhere keeps the defaults
    compiled = compiles(first, learning_starts, runs[0].step)
    with graphs.settings(graphs=first.cuda_graphs, compile=compiled):
        learner = algo.Learner(template, hyper, seeds, torch.device(first.device))
    metas = [run.metadata(template) for run in runs]

    observations, episodes = [], []
    if any(state is not None for state in states):
        learner.load_state_dict(stack_runs([state["learner"] for state in states]))
    if resident.trains_on_device(first, algo.Learner):
        resident.collect(learner, envs, runs, states, on_episode, threads, learning_starts)
        return
    for k, (run, state) in enumerate(zip(runs, states)):
        if state is None:
            options = learner.episode_options(k, 0)
            obs, episode = _begin(envs, k, seeds[k].integer("env"), options)
        elif not getattr(envs, "replays", True):  # the twin: start that episode again
            set_rng_state(warmup[k], state["warmup"])
            saved = state["episode"]
            envs.set_rng_state(k, saved["env_rng"])
            options = _options(saved, run.checkpoint_path)
            obs, episode = _begin(envs, k, saved["seed"], options)
        else:  # restore the loop's generator, then replay the episode in progress
            set_rng_state(warmup[k], state["warmup"])
            obs, episode = _replay(envs, k, state["episode"], run.checkpoint_path)
        observations.append(obs)
        episodes.append(episode)
    obs = np.stack(observations)

    def checkpoint(interrupted: bool = False) -> None:
        """Every run's checkpoint of the loop's state at the end of a step."""
        state = learner.state_dict()
        check_runs_first(state, group)  # a wrong layout: one line now, not at resume
        for k, run in enumerate(runs):
            slice_k = {
                "learner": run_slice(state, k),
                "warmup": rng_state(warmup[k]),
                "episode": episodes[k].state(obs[k]),
            }
            run.save(slice_k, interrupted)

    step, steps, group = runs[0].step, first.steps, len(runs)
    bar = runs[0].progress(group)
    ctrl_c = StepBoundary()  # Ctrl-C: a checkpoint at the end of its step, then stop
    try:
        ctrl_c.hold()
        while step < steps:
            if step < learning_starts:
                actions = [uniform(template.action_space, rng) for rng in warmup]
            else:
                actions = learner.act(obs)
                _check_actions(actions, step + 1, runs)
            results = envs.step(actions)
            next_obs = np.stack([r[0] for r in results])
            rewards = np.array([r[1] for r in results], dtype=np.float64)
            terminated = np.array([r[2] for r in results], dtype=bool)
            step += 1
            for run in runs:
                run.step = step
            # a truncated transition keeps terminated=0: its target bootstraps from next_obs
            learner.observe(obs, actions, rewards, next_obs, terminated, [r[3] for r in results])

            if step > learning_starts:
                losses = learner.update(step)
                if step % 1000 == 0:
                    values = {name: v.cpu().tolist() for name, v in losses.items()}
                    for k, run in enumerate(runs):
                        run.log({f"losses/{n}": v[k] for n, v in values.items()})
            if runs[0].eval_due():
                for k, run in enumerate(runs):
                    run.evaluate(export_policies(learner, k, metas[k])["policy"])

            for k, episode in enumerate(episodes):
                episode.actions.append(actions[k])
                episode.ret += rewards[k]
                episode.length += 1
                if terminated[k] or episode.length >= first.max_episode_steps:
                    # no transition crosses this reset
                    extra = learner.episode_end(k, episode.ret, episode.length)
                    runs[k].episode_end(episode.ret, episode.length, **extra)
                    if on_episode is not None:
                        on_episode(k, step, episode.ret)
                    options = learner.episode_options(k, step)
                    again = (
                        seeds[k].integer("env") if getattr(learner, "same_start", False) else None
                    )
                    next_obs[k], episodes[k] = _begin(envs, k, again, options)
                    threads.poll()
            obs = next_obs

            if runs[0].checkpoint_due():
                checkpoint()
                runs[0].check_stop()
            bar.update(group)
            if ctrl_c.requested:  # Ctrl-C came during this step: keep its end, then stop
                if runs[0].saved_step != step:
                    checkpoint(interrupted=True)
                raise KeyboardInterrupt
    finally:
        ctrl_c.release()
        bar.close()
    for k, run in enumerate(runs):
        run.finish(
            export_policies(learner, k, metas[k]), {"steps": run.step, "episodes": run.episodes}
        )


def _finite(action: Any) -> bool:
    if isinstance(action, (tuple, list)) and action and not np.isscalar(action[0]):
        return all(_finite(part) for part in action)  # a two-player action: (agent, adversary)
    try:
        return bool(np.all(np.isfinite(np.asarray(action, dtype=np.float64))))
    except (TypeError, ValueError):
        return True  # not numbers: the env says what is wrong with it


def _check_actions(actions: Any, step: int, runs: list[Run]) -> None:
    """Stop at the first NaN/inf action a learner returns (MuJoCo would warn, reset its state
    and go on, and the run would end with a NaN policy written as if trained)."""
    for k, action in enumerate(actions):
        if not _finite(action):
            config = runs[k].config
            raise Diverged(
                f"training stopped at step {step}: {config.algo} returned a non-finite action "
                f"for seed {config.seed} ({np.asarray(action, dtype=object).tolist()}); nothing "
                "was written past the last checkpoint (the learner diverged: lower its learning "
                "rate or check its update)"
            )
