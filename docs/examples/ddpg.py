"""DDPG (Lillicrap et al. 2016, "Continuous control with deep reinforcement learning";
https://arxiv.org/abs/1509.02971), written against rrls' learner protocol alone.

The worked example of ``docs/algorithms.md``. Train it with every rrls tool::

    PYTHONPATH=docs/examples rrls train --algo ddpg:Learner --task hopper --steps 100000
    PYTHONPATH=docs/examples rrls benchmark --preset quick --algos td3,ddpg:Learner

One critic, no target smoothing, no delay: TD3 without its three fixes.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass
from typing import Any

import numpy as np
import torch

from rrls.agents import (
    Actor,
    Critic,
    Generators,
    NumpyActor,
    NumpyGenerators,
    ReplayBuffer,
    RunSeeds,
    deterministic,
    polyak,
    to_mlp_policy,
    transition_fields,
)
from rrls.agents import Learner as Base


@dataclass
class Config:
    """Hyper-parameters: every field is an ``rrls train`` option (``--learning-rate``...)."""

    learning_rate: float = 3e-4
    gamma: float = 0.99
    tau: float = 0.005
    exploration_noise: float = 0.1
    learning_starts: int = 25_000  # the loop acts uniformly at random until then
    batch_size: int = 256
    buffer_size: int = 1_000_000
    hidden: tuple[int, ...] = (256, 256)


class Learner(Base):
    """DDPG for a group of K runs (K = 1 for a run alone)."""

    Config = Config  # make_env: the nominal task by default (or define ``make_env`` here)

    def __init__(self, env: Any, config: Config, seeds: list[RunSeeds], device: Any) -> None:
        obs_dim = env.observation_space.shape[0]
        self.low, self.high = env.action_space.low, env.action_space.high
        act_dim, self.config = len(self.low), config
        init = Generators(seeds, "init")  # each run's own stream, from its seed
        self.actor = Actor(obs_dim, act_dim, config.hidden, self.low, self.high, init).to(device)
        self.critic = Critic(obs_dim + act_dim, config.hidden, init, n=1).to(device)
        self.actor_target = copy.deepcopy(self.actor).requires_grad_(False)
        self.critic_target = copy.deepcopy(self.critic).requires_grad_(False)
        self.actor_opt = torch.optim.Adam(self.actor.parameters(), lr=config.learning_rate)
        self.critic_opt = torch.optim.Adam(self.critic.parameters(), lr=config.learning_rate)
        self.rngs = NumpyGenerators(seeds, "explore")
        self.buffer = ReplayBuffer(
            config.buffer_size, transition_fields(obs_dim, (act_dim,)), device, seeds
        )
        self.fast = NumpyActor(self.actor) if torch.device(device).type == "cpu" else None
        self.sigma = (self.high - self.low) / 2 * config.exploration_noise

    def act(self, obs: np.ndarray) -> list[Any]:
        mean = deterministic(self.actor, obs, self.fast)
        noise = np.stack([rng.normal(0.0, self.sigma) for rng in self.rngs])
        return list(np.clip(mean + noise, self.low, self.high).astype(np.float32))

    def observe(self, obs, actions, rewards, next_obs, terminated, infos) -> None:
        self.buffer.add(
            obs=obs, action=actions, reward=rewards, next_obs=next_obs, terminated=terminated
        )

    def update(self, step: int) -> dict[str, torch.Tensor]:
        cfg = self.config
        data = self.buffer.gather(self.buffer.draw(cfg.batch_size))
        s, a, s2 = data["obs"], data["action"], data["next_obs"]
        with torch.no_grad():
            q_next = self.critic_target(torch.cat((s2, self.actor_target(s2)), -1))[:, 0]
            y = data["reward"] + cfg.gamma * (1 - data["terminated"]) * q_next
        critic_loss = (self.critic(torch.cat((s, a), -1))[:, 0] - y).square().mean(-1)  # (K,)
        self.critic_opt.zero_grad()
        critic_loss.sum().backward()  # the sum over runs: each run's gradient is its own
        self.critic_opt.step()
        actor_loss = -self.critic.q1(torch.cat((s, self.actor(s)), -1)).mean(-1)
        self.actor_opt.zero_grad()
        actor_loss.sum().backward(inputs=list(self.actor.parameters()))
        self.actor_opt.step()
        polyak(self.actor_target, self.actor, cfg.tau)
        polyak(self.critic_target, self.critic, cfg.tau)
        return {"critic_loss": critic_loss.detach(), "actor_loss": actor_loss.detach()}

    def state_dict(self) -> dict[str, Any]:
        nets = ("actor", "critic", "actor_target", "critic_target", "actor_opt", "critic_opt")
        state = {name: getattr(self, name).state_dict() for name in nets}
        return {**state, "explore": self.rngs.state_dict(), "buffer": self.buffer.state_dict()}

    def load_state_dict(self, state: dict[str, Any]) -> None:
        for name, value in state.items():
            target = {"explore": self.rngs}.get(name) or getattr(self, name)
            target.load_state_dict(value)

    def export(self, k: int) -> dict[str, Any]:
        return {"policy": to_mlp_policy(self.actor, k)}
