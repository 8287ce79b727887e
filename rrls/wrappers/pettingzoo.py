"""A PettingZoo ``ParallelEnv`` view of the two-player games.

``protagonist`` plays the agent's action, ``adversary`` the second component of a
:class:`~rrls.wrappers.DynamicAdversarial` or :class:`~rrls.wrappers.ProbabilisticActionRobust`
env; both observe the env's observation; rewards are zero-sum.

>>> import gymnasium as gym
>>> from rrls.wrappers.pettingzoo import TwoPlayerParallelEnv
>>> game = TwoPlayerParallelEnv(gym.make("rrls/robust-hopper-adversarial-2d-v0"))
>>> obs, infos = game.reset(seed=0)
>>> sorted(obs)
['adversary', 'protagonist']
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
from gymnasium import spaces

from rrls.extras import install_hint
from rrls.interface import all_params

try:
    from pettingzoo import ParallelEnv
except ImportError as exc:  # pragma: no cover - exercised only without the extra
    raise ImportError(
        f"the PettingZoo view needs PettingZoo: {install_hint('pettingzoo')}"
    ) from exc

PROTAGONIST, ADVERSARY = "protagonist", "adversary"


class TwoPlayerParallelEnv(ParallelEnv):
    """Zero-sum ``ParallelEnv`` over a Gymnasium env with a ``Tuple(agent, adversary)`` action.

    ``reset(options=...)`` forwards only the env's parameter names (PettingZoo's API test passes
    arbitrary options); other keys are ignored.
    """

    metadata = {"name": "rrls_two_player_v0", "render_modes": ["rgb_array"]}

    def __init__(self, env: gym.Env) -> None:
        space = env.action_space
        if not isinstance(space, spaces.Tuple) or len(space.spaces) != 2:
            raise TypeError(f"needs a two-player env with a Tuple action space, got {space}")
        self.env = env
        self.possible_agents = [PROTAGONIST, ADVERSARY]
        self.agents: list[str] = []
        self._action_spaces = dict(zip(self.possible_agents, space.spaces))
        self._param_names = set(all_params(env))
        self.render_mode = env.render_mode

    def observation_space(self, agent: str) -> spaces.Space:
        return self.env.observation_space

    def action_space(self, agent: str) -> spaces.Space:
        return self._action_spaces[agent]

    def reset(self, seed: int | None = None, options: dict[str, Any] | None = None):
        params = {k: v for k, v in (options or {}).items() if k in self._param_names}
        obs, info = self.env.reset(seed=seed, options=params or None)
        self.agents = list(self.possible_agents)
        return {a: obs for a in self.agents}, {a: dict(info) for a in self.agents}

    def step(self, actions: dict[str, Any]):
        missing = [a for a in self.agents if a not in actions]
        if missing:
            raise ValueError(f"actions missing for {missing}")
        obs, reward, terminated, truncated, info = self.env.step(
            (actions[PROTAGONIST], actions[ADVERSARY])
        )
        agents = self.agents
        rewards = {PROTAGONIST: float(reward), ADVERSARY: -float(reward)}
        if terminated or truncated:
            self.agents = []
        return (
            {a: obs for a in agents},
            {a: rewards[a] for a in agents},
            {a: bool(terminated) for a in agents},
            {a: bool(truncated) for a in agents},
            {a: dict(info) for a in agents},
        )

    def render(self):
        return self.env.render()

    def close(self) -> None:
        self.env.close()

    def state(self):
        raise NotImplementedError("the game has no global state beyond the shared observation")


__all__ = ["TwoPlayerParallelEnv"]
