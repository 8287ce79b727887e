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
from rrls.agents.core import TD3, TD3Config, Update, hp
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
    """Two TD3 learners, one replay buffer each (the adversary's rewards negated), per run."""

    def __init__(
        self,
        env: Any,
        config: Config,
        runs: list[TrainConfig],
        rngs: list[np.random.Generator],
    ) -> None:
        obs_dim = env.observation_space.shape[0]
        self.spaces = env.action_space.spaces
        self.config = config
        seeds, device = [r.seed for r in runs], runs[0].device
        self.players, self.buffer_list = [], []
        for i, space in enumerate(self.spaces):
            own = [s + 1000 * i for s in seeds]
            self.players.append(
                TD3(obs_dim, space.shape[0], space.low, space.high, config, own, device)
            )
            self.buffer_list.append(
                ReplayBuffer(
                    min(config.buffer_size, runs[0].steps),
                    transition_fields(obs_dim, space.shape),
                    device,
                    [s + 2 for s in own],
                )
            )
        self.actor, self.adversary = (p.actor for p in self.players)
        self._update = Update(self._compute, self.players[0].device, runs[0].cuda_graphs)
        self.game = {"game": "adversarial", "uncertainty": runs[0].uncertainty}

    def act(self, obs: np.ndarray, rngs: list[np.random.Generator], warmup: bool) -> list[Any]:
        if warmup:
            return [
                tuple(rng.uniform(s.low, s.high).astype(np.float32) for s in self.spaces)
                for rng in rngs
            ]
        return list(zip(*(player.explore(obs, rngs) for player in self.players)))

    def store(self, obs, actions, rewards, next_obs, terminated, infos) -> None:  # noqa: ANN001
        # zero-sum: the adversary learns from -reward; truncation bootstraps for both
        for i, (buffer, sign) in enumerate(zip(self.buffer_list, (1.0, -1.0))):
            buffer.add(
                obs=obs,
                action=np.stack([a[i] for a in actions]),
                reward=sign * rewards,
                next_obs=next_obs,
                terminated=terminated,
            )

    def learning(self, step: int) -> int:
        """0 while the protagonist's phase, 1 during the adversary's (counted from the first
        update, so the first phase is a whole one)."""
        return (step - self.config.learning_starts - 1) // self.config.phase_steps % 2

    def update(self, step: int, update_actor: bool) -> dict[str, torch.Tensor]:
        i, size = self.learning(step), self.config.batch_size
        inputs = {"idx": self.buffer_list[i].draw(size), "eps": self.players[i].draw(size)}
        losses = self._update((i, update_actor), inputs)
        name = ("protagonist", "adversary")[i]
        return {f"{name}_{k}": v for k, v in losses.items()}

    def _compute(self, variant: tuple[int, bool], x: dict[str, torch.Tensor]) -> dict:
        """The device work of an update: the learning player's TD3 step."""
        i, update_actor = variant
        batch = self.buffer_list[i].gather(x["idx"])
        return self.players[i].update(batch, x["eps"], update_actor)

    def episode_end(self, k: int, episode_return: float, length: int) -> dict[str, float]:
        return {"charts/adversary_return": -episode_return}

    def stacked(self) -> dict[str, torch.Tensor]:
        return {k: v for i, p in enumerate(self.players) for k, v in p.stacked(f"p{i}").items()}

    def shared(self) -> dict[str, torch.Tensor]:
        return {k: v for i, p in enumerate(self.players) for k, v in p.shared(f"p{i}").items()}

    def generators(self) -> dict[str, list[torch.Generator]]:
        return {k: v for i, p in enumerate(self.players) for k, v in p.generators(f"p{i}").items()}

    def buffers(self) -> list[Any]:
        return self.buffer_list
