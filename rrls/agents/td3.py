"""TD3 (Fujimoto et al. 2018, "Addressing Function Approximation Error in Actor-Critic Methods").

The paper's non-robust baseline: TD3 trained on the nominal task. Its learner acts
``π(s) + N(0, σ)`` (uniformly at random during the warm-up), stores each transition once, and
takes one TD3 step per env step (``rrls.agents.core.TD3``: the critics every step, the actor and
the targets every ``policy_frequency``). Domain Randomization is this learner on a randomised
environment. The loop around it is ``rrls.agents.loop``.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import torch

from rrls.agents.common import TrainConfig, task_env
from rrls.agents.core import TD3, TD3Config
from rrls.agents.loop import Learner as _Learner
from rrls.agents.replay import ReplayBuffer, transition_fields

Config = TD3Config  # the paper's TD3 table, nothing more


def make_env(task: str, uncertainty: str, config: TD3Config) -> Any:
    """The nominal task: TD3 never sees the uncertainty set (it is only evaluated over it)."""
    return task_env(task)[0]


class Learner(_Learner):
    """One TD3 agent and its replay buffer."""

    def __init__(
        self, env: Any, config: TD3Config, run: TrainConfig, rng: np.random.Generator
    ) -> None:
        obs_dim = env.observation_space.shape[0]
        self.low, self.high = env.action_space.low, env.action_space.high
        act_dim = len(self.low)
        self.config = config
        self.agent = TD3(
            obs_dim, act_dim, self.low, self.high, config, seed=run.seed, device=run.device
        )
        self.actor = self.agent.actor
        self.buffer = ReplayBuffer(
            min(config.buffer_size, run.steps),
            transition_fields(obs_dim, (act_dim,)),
            device=run.device,
            seed=run.seed + 2,
        )

    def act(self, obs: np.ndarray, rng: np.random.Generator, warmup: bool) -> np.ndarray:
        if warmup:
            return rng.uniform(self.low, self.high).astype(np.float32)
        return self.agent.explore(obs, rng)

    def store(self, obs, action, reward, next_obs, terminated, info) -> None:  # noqa: ANN001
        self.buffer.add(
            obs=obs, action=action, reward=reward, next_obs=next_obs, terminated=float(terminated)
        )

    def update(self, step: int, update_actor: bool) -> dict[str, torch.Tensor]:
        return self.agent.update(self.buffer.sample(self.config.batch_size), update_actor)

    def state_dict(self) -> dict[str, Any]:
        return {"agent": self.agent.state_dict(), "buffer": self.buffer.state_dict()}

    def load_state_dict(self, state: dict[str, Any]) -> None:
        self.agent.load_state_dict(state["agent"])
        self.buffer.load_state_dict(state["buffer"])
