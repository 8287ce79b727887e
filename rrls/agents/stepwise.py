"""The CPU envs' collector: a group's envs stepped one env step at a time (a block of one step),
for the driver (``rrls.agents.driver``).

What it owns: acting (uniformly random from each run's ``"warmup"`` stream before the warm-up
ends, the learner's actions after, a non-finite one refused as ``Diverged``), time limits (an
episode truncated at ``max_episode_steps`` bootstraps, a terminated one does not, and no
transition crosses a reset), storing and updating, each episode's start (the run's ``"env"``
seed first, the learner's reset options) and the episode in progress that a checkpoint keeps:
its first state's generator, seed, options and actions, replayed on resume so that the resumed
run continues bit for bit.

The twin's envs for learners without the device methods (``rrls.agents.twin_envs.TwinEnvs``,
``replays = False``) go through here too: their episode in progress begins again on resume
instead of being replayed.
"""

from __future__ import annotations

import contextlib
import json
from pathlib import Path
from typing import Any

import numpy as np
import torch

from rrls.agents.config import Diverged
from rrls.agents.driver import Advance
from rrls.agents.streams import RunSeeds, rng_state, set_rng_state
from rrls.files import loads_json


def uniform(space: Any, rng: np.random.Generator) -> Any:
    """A uniformly random action of a ``Box`` (or of each ``Box`` of a ``Tuple``) space."""
    if hasattr(space, "spaces"):
        return tuple(uniform(s, rng) for s in space.spaces)
    return rng.uniform(space.low, space.high).astype(np.float32)


class Episode:
    """How run ``k``'s current episode began and what it did: a checkpoint taken mid-episode
    replays it (same generator, same reset, same actions: the same physics) on resume."""

    def __init__(self, env_rng: str, seed: int | None, options: dict | None) -> None:
        self.env_rng, self.seed, self.options = env_rng, seed, options
        self.actions: list[Any] = []
        self.ret, self.length = 0.0, 0

    def state(self, obs: np.ndarray) -> dict[str, Any]:
        """The checkpoint's record of the episode, ``obs`` its current observation."""
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


def begin(envs: Any, k: int, seed: int | None, options: dict | None) -> tuple:
    """Run ``k``'s new episode: its first observation and its ``Episode``."""
    state, obs = envs.begin(k, seed, options)  # one round trip to an env worker, not two
    return obs, Episode(state, seed, options)


def saved_options(saved: dict[str, Any], path: Path) -> Any:
    """The reset options of the episode a checkpoint was taken in (JSON in the checkpoint)."""
    return loads_json(saved["options"], f"{path}: the episode's reset options")


def replay(envs: Any, k: int, saved: dict[str, Any], path: Path) -> tuple:
    """Re-run the episode a checkpoint was taken in, up to the checkpoint."""
    envs.set_rng_state(k, saved["env_rng"])
    obs, episode = begin(envs, k, saved["seed"], saved_options(saved, path))
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


class StepCollector:
    """A group's envs (``rrls.agents.envs``' ``LocalEnvs`` or worker processes, or the twin's
    ``TwinEnvs``) and its learner, one env step per ``advance``.

    ``action_space``: one run's; ``seeds``: the runs' seeds; ``paths``: their checkpoints' paths
    (named in a failed replay); ``algo``: named in ``Diverged``.
    """

    block = 1

    def __init__(
        self,
        envs: Any,
        learner: Any,
        action_space: Any,
        seeds: list[int],
        starts: int,
        max_episode_steps: int,
        paths: list[Path],
        algo: str,
    ) -> None:
        self.envs, self.learner, self.space = envs, learner, action_space
        self.seeds, self.starts, self.limit = seeds, starts, max_episode_steps
        self.paths, self.algo = paths, algo
        self.streams = [RunSeeds(s) for s in seeds]
        self.warmup = [s.numpy("warmup") for s in self.streams]
        self.episodes: list[Episode] = []
        self.obs = np.empty(0)

    def running(self) -> contextlib.AbstractContextManager[Any]:
        return contextlib.nullcontext()

    def start(self, states: list[dict[str, Any] | None]) -> None:
        observations = []
        for k, state in enumerate(states):
            if state is None:
                options = self.learner.episode_options(k, 0)
                obs, episode = begin(self.envs, k, self.streams[k].integer("env"), options)
            elif not getattr(self.envs, "replays", True):  # the twin: start that episode again
                set_rng_state(self.warmup[k], state["warmup"])
                saved = state["episode"]
                self.envs.set_rng_state(k, saved["env_rng"])
                options = saved_options(saved, self.paths[k])
                obs, episode = begin(self.envs, k, saved["seed"], options)
            else:  # restore the loop's generator, then replay the episode in progress
                set_rng_state(self.warmup[k], state["warmup"])
                obs, episode = replay(self.envs, k, state["episode"], self.paths[k])
            observations.append(obs)
            self.episodes.append(episode)
        self.obs = np.stack(observations)

    def advance(self, step: int, n: int) -> Advance:
        assert n == 1, "the CPU envs step one step at a time"
        learner, obs = self.learner, self.obs
        if step < self.starts:
            actions = [uniform(self.space, rng) for rng in self.warmup]
        else:
            actions = learner.act(obs)
            self._check(actions, step + 1)
        results = self.envs.step(actions)
        next_obs = np.stack([r[0] for r in results])
        rewards = np.array([r[1] for r in results], dtype=np.float64)
        terminated = np.array([r[2] for r in results], dtype=bool)
        step += 1
        # a truncated transition keeps terminated=0: its target bootstraps from next_obs
        learner.observe(obs, actions, rewards, next_obs, terminated, [r[3] for r in results])
        out = Advance()
        if step > self.starts:
            out.losses = learner.update(step)
        for k, episode in enumerate(self.episodes):
            episode.actions.append(actions[k])
            episode.ret += rewards[k]
            episode.length += 1
            if terminated[k] or episode.length >= self.limit:
                out.ends.append((0, k, episode.ret, episode.length))
        self.obs = next_obs  # an ended episode's row is replaced by its next first state
        return out

    def next_episode(self, k: int, step: int) -> None:
        options = self.learner.episode_options(k, step)
        same = getattr(self.learner, "same_start", False)  # every episode from the first state
        again = self.streams[k].integer("env") if same else None
        self.obs[k], self.episodes[k] = begin(self.envs, k, again, options)

    def state(self, k: int) -> dict[str, Any]:
        return {"warmup": rng_state(self.warmup[k]), "episode": self.episodes[k].state(self.obs[k])}

    def _check(self, actions: Any, step: int) -> None:
        """Stop at the first NaN/inf action a learner returns (MuJoCo would warn, reset its
        state and go on, and the run would end with a NaN policy written as if trained)."""
        for k, action in enumerate(actions):
            if not finite(action):
                raise Diverged(
                    f"training stopped at step {step}: {self.algo} returned a non-finite action "
                    f"for seed {self.seeds[k]} ({np.asarray(action, dtype=object).tolist()}); "
                    "nothing was written past the last checkpoint (the learner diverged: lower "
                    "its learning rate or check its update)"
                )


def finite(action: Any) -> bool:
    """Whether an action (or each part of a two-player one) holds finite numbers only."""
    if isinstance(action, (tuple, list)) and action and not np.isscalar(action[0]):
        return all(finite(part) for part in action)  # a two-player action: (agent, adversary)
    try:
        return bool(np.all(np.isfinite(np.asarray(action, dtype=np.float64))))
    except (TypeError, ValueError):
        return True  # not numbers: the env says what is wrong with it


__all__ = ["Episode", "StepCollector", "begin", "finite", "replay", "saved_options", "uniform"]
