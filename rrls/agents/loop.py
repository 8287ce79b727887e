"""The one collection loop every baseline runs: an algorithm only brings its ``Learner``.

The loop owns what the five algorithms share, so it is written once: the environment and its
seeding, the uniformly random warm-up, acting, time limits (an episode truncated at
``max_episode_steps`` bootstraps, a terminated one does not, and no transition crosses a
reset), when updates happen, periodic evaluation, checkpoints taken at episode ends and the
bitwise resume from them, logs and the export of the final policies.

An algorithm module (``td3``, ``dr``, ``rarl``, ``nrmdp``, ``m2td3``) holds its paper reference,
its hyper-parameters as one dataclass ``Config`` (the paper's values; ``rrls train`` offers
every field as an option), ``make_env(task, uncertainty, config)`` and a ``Learner``: what it
acts, what it stores and how it updates.
"""

from __future__ import annotations

import importlib
import json
from collections.abc import Callable
from functools import partial
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np
import torch

from rrls.agents.common import (
    ALGOS,
    Run,
    TrainConfig,
    process_settings,
    rng_state,
    set_rng_state,
)
from rrls.agents.core import TD3Config
from rrls.agents.envs import make_envs


class Learner:
    """What an algorithm plugs into the loop, for a group of ``K`` runs (a run alone: ``K = 1``).

    ``actor`` holds the runs' policies (evaluated and exported as each run's ``policy.npz``);
    ``adversary``, if any, is exported as ``adversary.npz`` with ``game`` in its metadata.
    Observations, rewards and flags come as arrays with the runs first; actions as one env
    action per run. A run's checkpoint is its slice of every stacked tensor (``stacked``), the
    group's common counters (``shared``), its own generators and replay rows.
    """

    actor: Any
    adversary: Any = None
    game: dict[str, Any] | None = None

    def act(self, obs: np.ndarray, rngs: list[np.random.Generator], warmup: bool) -> list[Any]:
        """Each run's env action: uniformly random while ``warmup``, else explore."""
        raise NotImplementedError

    def store(
        self,
        obs: np.ndarray,
        actions: list[Any],
        rewards: np.ndarray,
        next_obs: np.ndarray,
        terminated: np.ndarray,
        infos: list[dict[str, Any]],
    ) -> None:
        """Write the step's transitions to the replay buffer(s); ``terminated`` only, never
        truncation."""
        raise NotImplementedError

    def update(self, step: int, update_actor: bool) -> dict[str, torch.Tensor]:
        """The gradient steps of one env step, for every run; returns ``(K,)`` losses (logged
        every 1 000 steps)."""
        raise NotImplementedError

    def episode_options(self, k: int, step: int, rng: np.random.Generator) -> dict | None:
        """``reset(options=...)`` for run ``k``'s next episode (M2TD3 picks its parameters)."""
        return None

    def episode_end(self, k: int, episode_return: float, length: int) -> dict[str, float]:
        """Called at each of run ``k``'s episode ends; returns extra scalars to log."""
        return {}

    def summary(self, k: int) -> dict[str, Any]:
        """Extra entries of run ``k``'s ``run.json``."""
        return {}

    # -- per-run checkpoints ----------------------------------------------------------------
    def stacked(self) -> dict[str, torch.Tensor]:
        """Every tensor whose leading dimension is the run, by name."""
        return {}

    def shared(self) -> dict[str, torch.Tensor]:
        """Tensors common to the group's runs (optimiser step counts)."""
        return {}

    def generators(self) -> dict[str, list[torch.Generator]]:
        """Each run's torch generators, by name."""
        return {}

    def buffers(self) -> list[Any]:
        return []

    def extra_state(self, k: int) -> dict[str, Any]:
        """Run ``k``'s other state (plain values and tensors)."""
        return {}

    def load_extra_state(self, k: int, state: dict[str, Any]) -> None:
        pass

    def policy(self, k: int, metadata: dict[str, Any]) -> Any:
        """Run ``k``'s actor as the ``MLPPolicy`` that is evaluated and saved."""
        return self.actor.to_mlp_policy(k, metadata)

    def adversary_policy(self, k: int, metadata: dict[str, Any]) -> Any:
        """Run ``k``'s adversary as an ``MLPPolicy`` (its metadata says so), if any."""
        if self.adversary is None:
            return None
        meta = {**metadata, "act_dim": self.adversary.act_dim, "role": "adversary"}
        return self.adversary.to_mlp_policy(k, meta)

    def actor_state(self, k: int) -> dict[str, torch.Tensor]:
        """Run ``k``'s actor tensors (``actor.pt``)."""
        return {n: t[k].detach().cpu().clone() for n, t in self.actor.named_parameters()}

    def state_dict(self, k: int) -> dict[str, Any]:
        """Run ``k``'s whole learner state: the same whatever group it was trained in."""
        return {
            "stacked": {n: t[k].detach().cpu().clone() for n, t in self.stacked().items()},
            "shared": {n: t.detach().cpu().clone() for n, t in self.shared().items()},
            "generators": {n: g[k].get_state() for n, g in self.generators().items()},
            "buffers": [b.state(k) for b in self.buffers()],
            "extra": self.extra_state(k),
        }

    @torch.no_grad()
    def load_state_dict(self, k: int, state: dict[str, Any]) -> None:
        for name, tensor in self.stacked().items():
            tensor[k].copy_(state["stacked"][name])
        for name, tensor in self.shared().items():
            if k and not torch.equal(tensor.cpu(), state["shared"][name]):
                raise ValueError("the runs of a group must resume from the same step")
            tensor.copy_(state["shared"][name])
        for name, gens in self.generators().items():
            gens[k].set_state(state["generators"][name])
        for buffer, saved in zip(self.buffers(), state["buffers"]):
            buffer.load(k, saved)
        self.load_extra_state(k, state["extra"])


#: runs per stacked learner on a CPU. Measured (``benchmarks/train_speed.py --groups``, Hopper,
#: 2 cores): 8 stacked runs step 1.3-1.5x faster than 8 single-threaded processes, but 32 stacked
#: runs are slower than 8 (their activations, ~16 MB a layer, leave the caches); a group of 32
#: is then four stacks of 8, updated one after the other in the same lockstep loop. A run's
#: numbers do not depend on its stack (see ``Learner.state_dict``).
CPU_STACK = 8


class Stacks(Learner):
    """Several stacked learners of one group, used as one: run ``k`` lives in one of them."""

    def __init__(self, parts: list[Learner]) -> None:
        self.parts = parts
        self.where = [(i, j) for i, p in enumerate(parts) for j in range(p.actor.group)]
        sizes = [p.actor.group for p in parts]
        self.bounds = [sum(sizes[:i]) for i in range(len(sizes) + 1)]
        self.actor, self.adversary, self.game = parts[0].actor, parts[0].adversary, parts[0].game

    def _slices(self) -> list[slice]:
        return [slice(a, b) for a, b in zip(self.bounds, self.bounds[1:])]

    def act(self, obs: np.ndarray, rngs: list[np.random.Generator], warmup: bool) -> list[Any]:
        return [
            a for p, s in zip(self.parts, self._slices()) for a in p.act(obs[s], rngs[s], warmup)
        ]

    def store(self, obs, actions, rewards, next_obs, terminated, infos) -> None:  # noqa: ANN001
        for p, s in zip(self.parts, self._slices()):
            p.store(obs[s], actions[s], rewards[s], next_obs[s], terminated[s], infos[s])

    def update(self, step: int, update_actor: bool) -> dict[str, torch.Tensor]:
        losses = [p.update(step, update_actor) for p in self.parts]
        return {name: torch.cat([part[name] for part in losses]) for name in losses[0]}

    def _call(self, method: str, k: int, *args: Any) -> Any:
        i, j = self.where[k]
        return getattr(self.parts[i], method)(j, *args)

    def episode_options(self, k: int, step: int, rng: np.random.Generator) -> dict | None:
        return self._call("episode_options", k, step, rng)

    def episode_end(self, k: int, episode_return: float, length: int) -> dict[str, float]:
        return self._call("episode_end", k, episode_return, length)

    def summary(self, k: int) -> dict[str, Any]:
        return self._call("summary", k)

    def policy(self, k: int, metadata: dict[str, Any]) -> Any:
        return self._call("policy", k, metadata)

    def adversary_policy(self, k: int, metadata: dict[str, Any]) -> Any:
        return self._call("adversary_policy", k, metadata)

    def actor_state(self, k: int) -> dict[str, torch.Tensor]:
        return self._call("actor_state", k)

    def state_dict(self, k: int) -> dict[str, Any]:
        return self._call("state_dict", k)

    def load_state_dict(self, k: int, state: dict[str, Any]) -> None:
        self._call("load_state_dict", k, state)


def algorithm(name: str) -> ModuleType:
    """The module of algorithm ``name`` (``rrls.agents.td3``, ...)."""
    if name not in ALGOS:
        raise ValueError(f"unknown algorithm {name!r}; valid: {', '.join(ALGOS)}")
    return importlib.import_module(f"rrls.agents.{name}")


def hyperparameters(config: TrainConfig) -> TD3Config:
    """The algorithm's ``Config`` with the run's overrides (``config.hyper``), validated."""
    cls = algorithm(config.algo).Config
    valid = set(cls.__dataclass_fields__)
    unknown = sorted(set(config.hyper) - valid)
    if unknown:
        raise ValueError(
            f"{config.algo} has no hyper-parameter {', '.join(map(repr, unknown))}; "
            f"valid: {', '.join(sorted(valid))}"
        )
    return cls(**config.hyper)


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

    The runs (typically different seeds) differ only in ``seed`` and ``out``; they are stacked
    (``K`` agents, one update call) and their envs step in lockstep. Each run keeps its own
    directory, checkpoint, logs and policy, and its numbers are those it has when trained alone
    (``tests/test_group.py``). Resumed runs that stopped at different steps are continued in
    groups of equal step. ``on_episode(k, step, return)`` is called at run ``k``'s episode ends.
    """
    if not configs:
        return []
    hyper = hyperparameters(configs[0])
    _check_group(configs, hyper)
    runs = [Run(c, resume, hyper) for c in configs]
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
            with process_settings(configs[0].threads) as threads:
                _train_together(
                    hyper, [runs[k] for k in members], [states[k] for k in members], hook, threads
                )
    finally:
        for run in reversed(runs):
            run.close()
    return [run.dir for run in runs]


def _check_group(configs: list[TrainConfig], hyper: TD3Config) -> None:
    """The runs of a group must differ only in seed and directory."""
    first, reference = configs[0], configs[0].identity(hyper)
    same = ("steps", "device", "eval_every", "eval_episodes", "eval_mesh", "checkpoint_every")
    for config in configs[1:]:
        identity = config.identity(hyperparameters(config))  # once per run, not per field
        diff = [k for k, v in reference.items() if k != "seed" and identity[k] != v]
        diff += [name for name in same if getattr(config, name) != getattr(first, name)]
        if diff:
            raise ValueError(
                f"runs trained together must differ only in seed and out; these differ: "
                f"{', '.join(sorted(set(diff)))}"
            )
    outs = [str(Path(c.out).resolve()) for c in configs]
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
        if self.actions:
            first = self.actions[0]
            if isinstance(first, tuple):
                parts = [
                    torch.as_tensor(np.stack([a[i] for a in self.actions]))
                    for i in range(len(first))
                ]
            else:
                parts = [torch.as_tensor(np.stack(self.actions))]
        return {
            "env_rng": self.env_rng,
            "seed": self.seed,
            "options": json.dumps(self.options),
            "tuple": bool(self.actions) and isinstance(self.actions[0], tuple),
            "actions": parts,
            "obs": torch.as_tensor(np.asarray(obs)),
        }


def _begin(
    envs: Any, k: int, seed: int | None, options: dict | None
) -> tuple[np.ndarray, _Episode]:
    episode = _Episode(envs.rng_state(k), seed, options)
    return envs.reset(k, seed, options), episode


def _replay(envs: Any, k: int, saved: dict[str, Any], path: Path) -> tuple[np.ndarray, _Episode]:
    """Re-run the episode a checkpoint was taken in, up to the checkpoint."""
    envs.set_rng_state(k, saved["env_rng"])
    obs, episode = _begin(envs, k, saved["seed"], json.loads(saved["options"]))
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


def _train_together(
    hyper: TD3Config,
    runs: list[Run],
    states: list[dict[str, Any] | None],
    on_episode: Callable[[int, int, float], None] | None,
    threads: Any,
) -> None:
    """The collection loop of one group of runs at the same step."""
    first = runs[0].config
    algo = algorithm(first.algo)
    make = partial(algo.make_env, first.task, first.uncertainty, hyper)
    template = make()  # spaces and metadata; the group's envs may live in worker processes
    envs = make_envs(make, len(runs), env_workers(first, len(runs)))
    try:
        _collect(algo, hyper, runs, states, on_episode, threads, template, envs)
    finally:
        envs.close()


def env_workers(config: TrainConfig, group: int) -> int:
    """``--env-workers``, or by default: none on a CPU (the update dominates), on a GPU one per
    8 envs of a group of 16 or more, within the cores."""
    if config.env_workers is not None:
        return config.env_workers
    if not config.device.startswith("cuda") or group < 16:
        return 0
    import os

    return max(0, min(group // 8, (os.cpu_count() or 1) - 1))


def _collect(
    algo: ModuleType,
    hyper: TD3Config,
    runs: list[Run],
    states: list[dict[str, Any] | None],
    on_episode: Callable[[int, int, float], None] | None,
    threads: Any,
    template: Any,
    envs: Any,
) -> None:
    first = runs[0].config
    configs = [run.config for run in runs]
    # warm-up actions, exploration noise, M2TD3's draws: each run's own generator
    rngs = [np.random.default_rng(c.seed) for c in configs]
    # on a CPU, stacks of at most CPU_STACK runs (cache-sized), updated one after the other
    size = len(runs) if first.device.startswith("cuda") else CPU_STACK
    bounds = list(range(0, len(runs), size)) + [len(runs)]
    parts = [
        algo.Learner(template, hyper, configs[a:b], rngs[a:b]) for a, b in zip(bounds, bounds[1:])
    ]
    learner: Learner = parts[0] if len(parts) == 1 else Stacks(parts)
    metas = [run.metadata(template, learner, k) for k, run in enumerate(runs)]

    observations, episodes = [], []
    for k, (run, state) in enumerate(zip(runs, states)):
        if state is None:
            options = learner.episode_options(k, 0, rngs[k])
            obs, episode = _begin(envs, k, run.config.seed, options)
        else:  # restore everything, then replay the episode in progress
            learner.load_state_dict(k, state["learner"])
            set_rng_state(rngs[k], state["rng"])
            obs, episode = _replay(envs, k, state["episode"], run.checkpoint_path)
        observations.append(obs)
        episodes.append(episode)
    obs = np.stack(observations)

    step, steps, group = runs[0].step, first.steps, len(runs)
    bar = runs[0].progress(group)
    try:
        while step < steps:
            actions = learner.act(obs, rngs, warmup=step < hyper.learning_starts)
            results = envs.step(actions)
            next_obs = np.stack([r[0] for r in results])
            rewards = np.array([r[1] for r in results], dtype=np.float64)
            terminated = np.array([r[2] for r in results], dtype=bool)
            step += 1
            for run in runs:
                run.step = step
            # a truncated transition keeps terminated=0: its target bootstraps from next_obs
            learner.store(obs, actions, rewards, next_obs, terminated, [r[3] for r in results])

            if step > hyper.learning_starts:
                losses = learner.update(step, step % hyper.policy_frequency == 0)
                if step % 1000 == 0:
                    values = {name: v.cpu().tolist() for name, v in losses.items()}
                    for k, run in enumerate(runs):
                        run.log({f"losses/{n}": v[k] for n, v in values.items()})
            if runs[0].eval_due():
                for k, run in enumerate(runs):
                    run.evaluate(learner.policy(k, metas[k]))

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
                    options = learner.episode_options(k, step, rngs[k])
                    next_obs[k], episodes[k] = _begin(envs, k, None, options)
                    threads.poll()
            obs = next_obs

            if runs[0].checkpoint_due():
                for k, run in enumerate(runs):
                    run.save(
                        {
                            "learner": learner.state_dict(k),
                            "rng": rng_state(rngs[k]),
                            "episode": episodes[k].state(obs[k]),
                        }
                    )
                runs[0].check_stop()
            bar.update(group)
    finally:
        bar.close()
    for k, run in enumerate(runs):
        run.finish(
            learner.policy(k, metas[k]),
            learner.actor_state(k),
            metas[k],
            {"steps": run.step, "episodes": run.episodes, **learner.summary(k)},
            adversary=learner.adversary_policy(k, metas[k]),
        )
