"""TD3 (Fujimoto et al. 2018, "Addressing Function Approximation Error in Actor-Critic Methods").

The paper's non-robust baseline: TD3 trained on the nominal task. Its learner acts
``π(s) + N(0, σ)`` (uniformly at random during the warm-up), stores each transition once, and
takes one TD3 step per env step (``rrls.agents.core.TD3``: the critics every step, the actor and
the targets every ``policy_frequency``). Domain Randomization is this learner on a randomised
environment. The loop around it is ``rrls.agents.loop``; the learner holds a group of runs
(different seeds) trained together.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import torch

from rrls.agents.common import TrainConfig, task_env
from rrls.agents.core import TD3, TD3Config, Update
from rrls.agents.loop import Learner as _Learner
from rrls.agents.replay import ReplayBuffer, transition_fields

Config = TD3Config  # the paper's TD3 table, nothing more


def make_env(task: str, uncertainty: str, config: TD3Config) -> Any:
    """The nominal task: TD3 never sees the uncertainty set (it is only evaluated over it)."""
    return task_env(task)[0]


class Learner(_Learner):
    """TD3 agents and their replay buffers, one per run."""

    def __init__(
        self,
        env: Any,
        config: TD3Config,
        runs: list[TrainConfig],
        rngs: list[np.random.Generator],
    ) -> None:
        obs_dim = env.observation_space.shape[0]
        self.low, self.high = env.action_space.low, env.action_space.high
        act_dim = len(self.low)
        self.config = config
        seeds, device = [r.seed for r in runs], runs[0].device
        self.agent = TD3(obs_dim, act_dim, self.low, self.high, config, seeds, device)
        self.actor = self.agent.actor
        self.buffer = ReplayBuffer(
            min(config.buffer_size, runs[0].steps),
            transition_fields(obs_dim, (act_dim,)),
            device,
            [s + 2 for s in seeds],
        )
        self._update = Update(self._compute, self.agent.device, runs[0].cuda_graphs)

    def act(self, obs: np.ndarray, rngs: list[np.random.Generator], warmup: bool) -> list[Any]:
        if warmup:
            return [rng.uniform(self.low, self.high).astype(np.float32) for rng in rngs]
        return list(self.agent.explore(obs, rngs))

    def store(self, obs, actions, rewards, next_obs, terminated, infos) -> None:  # noqa: ANN001
        self.buffer.add(
            obs=obs, action=actions, reward=rewards, next_obs=next_obs, terminated=terminated
        )

    def update(self, step: int, update_actor: bool) -> dict[str, torch.Tensor]:
        size = self.config.batch_size
        return self._update(
            update_actor, {"idx": self.buffer.draw(size), "eps": self.agent.draw(size)}
        )

    def _compute(self, update_actor: bool, x: dict[str, torch.Tensor]) -> dict[str, torch.Tensor]:
        """The device work of an update (``core.Update`` may capture it in a CUDA graph)."""
        return self.agent.update(self.buffer.gather(x["idx"]), x["eps"], update_actor)

    def stacked(self) -> dict[str, torch.Tensor]:
        return self.agent.stacked("agent")

    def shared(self) -> dict[str, torch.Tensor]:
        return self.agent.shared("agent")

    def generators(self) -> dict[str, list[torch.Generator]]:
        return self.agent.generators("agent")

    def buffers(self) -> list[Any]:
        return [self.buffer]
