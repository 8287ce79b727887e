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
- **Rate limit.** ``rate_limit=L`` (``rrls train --algo rarl --rate-limit L``) plays the game of
  Time-Constrained Robust MDPs (Zouitine et al., NeurIPS 2024): the adversary's parameter vector
  moves at most ``L`` per step in the set's normalised units (``DynamicAdversarial(...,
  rate_limit=L)``); the saved adversary records ``L``, so the dynamic evaluation replays that game.
- The final adversary is saved (``adversary.npz``) for the dynamic evaluation (paper Table 6).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import torch

from rrls.agents.common import hp, task_env
from rrls.agents.graphs import Update
from rrls.agents.learner import Learner as _Learner
from rrls.agents.nets import to_mlp_policy
from rrls.agents.replay import ReplayBuffer, transition_fields
from rrls.agents.seeds import NumpyGenerators, RunSeeds
from rrls.agents.td3 import TD3, TD3Config


@dataclass
class Config(TD3Config):
    """TD3's table for both players, plus the phase length."""

    phase_steps: int = hp(4000, "env steps per phase (protagonist, then adversary, ...)")
    rate_limit: float | None = hp(
        None,
        "TC-RMDP's rate-limited adversary: the parameters move at most this much per step, in "
        "the set's normalised units (default: none, RARL's unconstrained game)",
    )

    def __post_init__(self) -> None:
        super().__post_init__()
        if self.phase_steps < 1:
            raise ValueError(f"phase_steps must be >= 1, got {self.phase_steps}")
        if self.rate_limit is not None and not (
            isinstance(self.rate_limit, (int, float))
            and not isinstance(self.rate_limit, bool)
            and 0 < self.rate_limit < float("inf")
        ):
            raise ValueError(
                f"rate_limit must be a finite number > 0 (normalised units per step), "
                f"got {self.rate_limit!r}"
            )


def make_env(task: str, uncertainty: Any, config: Config, paper: bool = False) -> Any:
    """The two-player game over the set: parameters (``1d/2d/3d``) or forces (``rarl``), the
    adversary's moves rate-limited if ``config.rate_limit`` is set."""
    from rrls.wrappers import DynamicAdversarial

    return DynamicAdversarial(*task_env(task, uncertainty, paper), rate_limit=config.rate_limit)


PLAYERS = ("", "adversary.")  # generator names: the protagonist's, the adversary's


class Learner(_Learner):
    """Two TD3 players, one replay buffer each (the adversary's rewards negated), per run."""

    def __init__(self, env: Any, config: Config, seeds: list[RunSeeds], device: Any) -> None:
        obs_dim = env.observation_space.shape[0]
        self.spaces = env.action_space.spaces
        self.config = config
        self.players = [
            TD3(obs_dim, s.low, s.high, config, seeds, device, name=name)
            for s, name in zip(self.spaces, PLAYERS)
        ]
        self.buffers = [
            ReplayBuffer(
                config.buffer_size,
                transition_fields(obs_dim, s.shape),
                device,
                seeds,
                purpose=name + "replay",
            )
            for s, name in zip(self.spaces, PLAYERS)
        ]
        self.rngs = [NumpyGenerators(seeds, name + "explore") for name in PLAYERS]
        self._update = Update(self._compute, device)
        # the game the policies record (the set: the run's ``uncertainty``); the dynamic
        # evaluation (``evaluate_run_dynamic``) reads it back to replay the same game
        self.game: dict[str, Any] = {"game": "adversarial"}
        if config.rate_limit is not None:
            self.game["rate_limit"] = float(config.rate_limit)

    def act(self, obs: np.ndarray) -> list[Any]:
        cfg, per_player = self.config, []
        for player, rngs, space in zip(self.players, self.rngs, self.spaces):
            sigma = (space.high - space.low) / 2 * cfg.exploration_noise
            noise = np.stack([rng.normal(0.0, sigma) for rng in rngs])
            action = np.clip(player.act(obs) + noise, space.low, space.high)
            per_player.append(action.astype(np.float32))
        return list(zip(*per_player))

    def observe(self, obs, actions, rewards, next_obs, terminated, infos) -> None:  # noqa: ANN001
        # zero-sum: the adversary learns from -reward; truncation bootstraps for both
        for i, (buffer, sign) in enumerate(zip(self.buffers, (1.0, -1.0))):
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

    def update(self, step: int) -> dict[str, torch.Tensor]:
        i, size = self.learning(step), self.config.batch_size
        draws = {"idx": self.buffers[i].draw(size), "eps": self.players[i].draw(size)}
        losses = self._update((i, step % self.config.policy_frequency == 0), draws)
        name = ("protagonist", "adversary")[i]
        return {f"{name}_{k}": v for k, v in losses.items()}

    def _compute(self, variant: tuple[int, bool], x: dict[str, torch.Tensor]) -> dict:
        """The device work of an update: the learning player's TD3 step."""
        i, update_actor = variant
        player, data = self.players[i], self.buffers[i].gather(x["idx"])
        y = player.td_target(data, x["eps"])
        losses = {"critic_loss": player.critic_step(data["obs"], data["action"], y)}
        if update_actor:
            losses["actor_loss"] = player.actor_step(data["obs"])
            player.soft_update()
        return losses

    def episode_end(self, k: int, episode_return: float, length: int) -> dict[str, float]:
        return {"charts/adversary_return": -episode_return}

    def state_dict(self) -> dict[str, Any]:
        return {
            "players": [p.state_dict() for p in self.players],
            "buffers": [b.state_dict() for b in self.buffers],
            "explore": [r.state_dict() for r in self.rngs],
        }

    def load_state_dict(self, state: dict[str, Any]) -> None:
        parts = {"players": self.players, "buffers": self.buffers, "explore": self.rngs}
        for key, objects in parts.items():
            for obj, saved in zip(objects, state[key]):
                obj.load_state_dict(saved)

    def export(self, k: int) -> dict[str, Any]:
        return {
            name: to_mlp_policy(p.actor, k, self.game)
            for name, p in zip(("policy", "adversary"), self.players)
        }
