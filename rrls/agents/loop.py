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
from collections.abc import Callable
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np
import torch

from rrls.agents.common import ALGOS, Run, TrainConfig, rng_state, set_rng_state
from rrls.agents.core import TD3Config


class Learner:
    """What an algorithm plugs into the loop (defaults for what most algorithms do not need).

    ``actor`` is the policy that is evaluated and exported as ``policy.npz``; ``adversary``, if
    any, is exported as ``adversary.npz`` with ``game`` in its metadata.
    """

    actor: Any
    adversary: Any = None
    game: dict[str, Any] | None = None

    def act(self, obs: np.ndarray, rng: np.random.Generator, warmup: bool) -> Any:
        """The env action for ``obs``: uniformly random while ``warmup``, else explore."""
        raise NotImplementedError

    def store(
        self,
        obs: np.ndarray,
        action: Any,
        reward: float,
        next_obs: np.ndarray,
        terminated: bool,
        info: dict[str, Any],
    ) -> None:
        """Write the transition to the replay buffer(s); ``terminated`` only, never truncation."""
        raise NotImplementedError

    def update(self, step: int, update_actor: bool) -> dict[str, torch.Tensor]:
        """The gradient steps of one env step; returns losses (logged every 1 000 steps)."""
        raise NotImplementedError

    def episode_options(self, step: int, rng: np.random.Generator) -> dict[str, Any] | None:
        """``reset(options=...)`` for the next episode (M2TD3 picks its parameters here)."""
        return None

    def episode_end(self, episode_return: float, length: int) -> dict[str, float]:
        """Called at every episode end, before the checkpoint; returns extra scalars to log."""
        return {}

    def summary(self) -> dict[str, Any]:
        """Extra entries of ``run.json``."""
        return {}

    def state_dict(self) -> dict[str, Any]:
        raise NotImplementedError

    def load_state_dict(self, state: dict[str, Any]) -> None:
        raise NotImplementedError


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
    algo = algorithm(config.algo)
    hyper = hyperparameters(config)
    run = Run(config, resume, hyper)
    if run.finished:
        return run.dir
    env = algo.make_env(run.task, run.uncertainty, hyper)
    rng = np.random.default_rng(config.seed)  # warm-up actions, exploration noise, M2TD3's draws
    learner: Learner = algo.Learner(env, hyper, config, rng)
    meta = run.metadata(env, learner)

    state = run.load()
    if state is not None:  # restore everything, then redo the reset the checkpoint preceded
        learner.load_state_dict(state["learner"])
        set_rng_state(rng, state["rng"])
        set_rng_state(env.unwrapped.np_random, state["env_rng"])
    obs, _ = env.reset(
        seed=config.seed if state is None else None,
        options=learner.episode_options(run.step, rng),
    )

    bar = run.progress()
    episode_return, episode_length = 0.0, 0
    try:
        while run.step < config.steps:
            action = learner.act(obs, rng, warmup=run.step < hyper.learning_starts)
            next_obs, reward, terminated, _, info = env.step(action)
            run.step += 1
            episode_return += reward
            episode_length += 1
            truncated = episode_length >= config.max_episode_steps
            # a truncated transition keeps terminated=0: its target bootstraps from next_obs
            learner.store(obs, action, reward, next_obs, terminated, info)
            obs = next_obs

            if run.step > hyper.learning_starts:
                losses = learner.update(run.step, run.step % hyper.policy_frequency == 0)
                if run.step % 1000 == 0:
                    run.log({f"losses/{k}": v.item() for k, v in losses.items()})
            if run.eval_due():
                run.evaluate(learner.actor, meta)

            if terminated or truncated:  # no transition crosses this reset
                extra = learner.episode_end(episode_return, episode_length)
                run.episode_end(episode_return, episode_length, **extra)
                if on_episode is not None:
                    on_episode(run.step, episode_return)
                episode_return, episode_length = 0.0, 0
                if run.checkpoint_due():
                    run.save(
                        {
                            "learner": learner.state_dict(),
                            "rng": rng_state(rng),
                            "env_rng": rng_state(env.unwrapped.np_random),
                        }
                    )
                obs, _ = env.reset(options=learner.episode_options(run.step, rng))
            bar.update(1)
    finally:
        run.close()
    return run.finish(
        learner.actor,
        meta,
        {"steps": run.step, "episodes": run.episodes, **learner.summary()},
        adversary=learner.adversary,
        adversary_metadata={"role": "adversary"},
    )
