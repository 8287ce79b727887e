"""RARL (Pinto et al. 2017, "Robust Adversarial Reinforcement Learning"), on the TD3 core.

A protagonist and an adversary, both TD3 learners, play the zero-sum game of
``DynamicAdversarial``: each step the adversary picks the perturbation and the protagonist acts;
the protagonist maximises the reward, the adversary ``-reward``. Both act at every step; their
updates alternate in phases, as in RARL's Algorithm 1: ``phase_steps`` env steps during which
only the protagonist learns (the adversary plays its current policy), then as many during which
only the adversary learns.

- **Set.** By default the paper's benchmark set (RRLS §5 trains every baseline on the 3D
  parameter set, 2D on InvertedPendulum): the adversary chooses the physical parameters every
  step. ``--uncertainty rarl`` gives RARL's own game, forces on named bodies (RRLS Table 3).
- **Phases.** RARL's reference code (``lerrel/rllab-adv``, ``train_adversary.py``) alternates
  ``n_pro_itr = n_adv_itr = 1`` TRPO iteration per player, each on a fresh batch of
  ``batch_size = 4000`` env steps collected with both players acting; here a phase is those
  4 000 env steps, each followed by one off-policy update of the learning player.
- The final adversary is saved (``adversary.npz``) for the dynamic evaluation (paper Table 6).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import torch

from rrls.agents.common import TrainConfig, task_env
from rrls.agents.core import TD3, TD3Config, hp
from rrls.agents.loop import Learner as _Learner
from rrls.agents.replay import ReplayBuffer, transition_fields


@dataclass
class Config(TD3Config):
    """TD3's table for both players, plus the phase length."""

    phase_steps: int = hp(4000, "env steps per phase (protagonist, then adversary, ...)")

    def __post_init__(self) -> None:
        super().__post_init__()
        if self.phase_steps < 1:
            raise ValueError(f"phase_steps must be >= 1, got {self.phase_steps}")


def make_env(task: str, uncertainty: str, config: Config) -> Any:
    """The two-player game over the set: parameters (``1d/2d/3d``) or forces (``rarl``)."""
    from rrls.wrappers import DynamicAdversarial

    return DynamicAdversarial(*task_env(task, uncertainty))


class Learner(_Learner):
    """Two TD3 learners, one replay buffer each (the adversary's rewards negated)."""

    def __init__(
        self, env: Any, config: Config, run: TrainConfig, rng: np.random.Generator
    ) -> None:
        obs_dim = env.observation_space.shape[0]
        self.spaces = env.action_space.spaces
        self.config = config
        self.players, self.buffers = [], []
        for i, space in enumerate(self.spaces):
            self.players.append(
                TD3(
                    obs_dim,
                    space.shape[0],
                    space.low,
                    space.high,
                    config,
                    seed=run.seed + 1000 * i,
                    device=run.device,
                )
            )
            self.buffers.append(
                ReplayBuffer(
                    min(config.buffer_size, run.steps),
                    transition_fields(obs_dim, space.shape),
                    device=run.device,
                    seed=run.seed + 2 + 1000 * i,
                )
            )
        self.actor, self.adversary = (p.actor for p in self.players)
        self.game = {"game": "adversarial", "uncertainty": run.uncertainty}

    def act(self, obs: np.ndarray, rng: np.random.Generator, warmup: bool) -> tuple:
        if warmup:
            return tuple(rng.uniform(s.low, s.high).astype(np.float32) for s in self.spaces)
        return tuple(player.explore(obs, rng) for player in self.players)

    def store(self, obs, action, reward, next_obs, terminated, info) -> None:  # noqa: ANN001
        # zero-sum: the adversary learns from -reward; truncation bootstraps for both
        for buffer, own, sign in zip(self.buffers, action, (1.0, -1.0)):
            buffer.add(
                obs=obs,
                action=own,
                reward=sign * reward,
                next_obs=next_obs,
                terminated=float(terminated),
            )

    def learning(self, step: int) -> int:
        """0 while the protagonist's phase, 1 during the adversary's (counted from the first
        update, so the first phase is a whole one)."""
        return (step - self.config.learning_starts - 1) // self.config.phase_steps % 2

    def update(self, step: int, update_actor: bool) -> dict[str, torch.Tensor]:
        i = self.learning(step)
        losses = self.players[i].update(
            self.buffers[i].sample(self.config.batch_size), update_actor
        )
        name = ("protagonist", "adversary")[i]
        return {f"{name}_{k}": v for k, v in losses.items()}

    def episode_end(self, episode_return: float, length: int) -> dict[str, float]:
        return {"charts/adversary_return": -episode_return}

    def state_dict(self) -> dict[str, Any]:
        return {
            "agents": [p.state_dict() for p in self.players],
            "buffers": [b.state_dict() for b in self.buffers],
        }

    def load_state_dict(self, state: dict[str, Any]) -> None:
        for player, buffer, saved, saved_buffer in zip(
            self.players, self.buffers, state["agents"], state["buffers"]
        ):
            player.load_state_dict(saved)
            buffer.load_state_dict(saved_buffer)
