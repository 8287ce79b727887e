"""Action-robust games (Tessler et al. 2019): NR-MDP and PR-MDP."""

from __future__ import annotations

from typing import Any, Literal

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from rrls.wrappers._checks import split_pair
from rrls.wrappers.access import ParamsForwarding


class ProbabilisticActionRobust(ParamsForwarding, gym.utils.RecordConstructorArgs):
    """The agent and an adversary both act; what the env executes mixes their actions.

    ``mode="nr"`` (NR-MDP, default): executes ``(1 - alpha) * a + alpha * a_adv``. This is the
    original RRLS code's convention (alpha weighs the *adversary*); the paper's text writes
    alpha on the agent, i.e. our alpha is its ``1 - alpha``.
    ``mode="pr"`` (PR-MDP): with probability ``alpha`` the adversary's action is executed
    instead of the agent's, the coin drawn from the env's seeded generator.

    The action space is ``Tuple(A, A)``; ``info["adversarial_reward"] = -reward``,
    ``info["executed_action"]`` holds what the env executed and, as in the original code,
    ``info["agent action"]`` / ``info["adversarial action"]`` the two actions given.

    >>> import numpy as np
    >>> from rrls.envs import RobustHopper
    >>> from rrls.wrappers import ProbabilisticActionRobust
    >>> env = ProbabilisticActionRobust(RobustHopper(), alpha=0.1)
    >>> _ = env.reset(seed=0)
    >>> *_, info = env.step((np.ones(3), -np.ones(3)))
    >>> [round(float(x), 2) for x in info["executed_action"]]
    [0.8, 0.8, 0.8]
    """

    def __init__(self, env: gym.Env, alpha: float = 0.1, mode: Literal["nr", "pr"] = "nr") -> None:
        gym.utils.RecordConstructorArgs.__init__(self, alpha=alpha, mode=mode)
        super().__init__(env)
        if (
            isinstance(alpha, bool)
            or not isinstance(alpha, (int, float, np.integer, np.floating))
            or not (np.isfinite(alpha) and 0.0 <= alpha <= 1.0)
        ):
            raise ValueError(f"alpha must be a number in [0, 1], got {alpha!r}")
        if mode not in ("nr", "pr"):
            raise ValueError(f"mode must be 'nr' (NR-MDP) or 'pr' (PR-MDP), got {mode!r}")
        self.alpha = float(alpha)
        self.mode = mode
        self.action_space = spaces.Tuple((env.action_space, env.action_space))
        self._step = 0

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        self._step = 0
        return self.env.reset(seed=seed, options=options)

    def step(self, action: Any):
        self._step += 1
        agent, adversary = split_pair(action, self.action_space, self._step)
        if self.mode == "nr":
            executed = (1.0 - self.alpha) * agent + self.alpha * adversary
        else:
            executed = adversary if self.np_random.random() < self.alpha else agent
        obs, reward, terminated, truncated, info = self.env.step(executed.astype(agent.dtype))
        info["adversarial_reward"] = -reward
        info["executed_action"] = executed
        info["agent action"] = agent
        info["adversarial action"] = adversary
        return obs, reward, terminated, truncated, info


class ConcatenateActions(ParamsForwarding):
    """Flat ``Box`` form of a two-player env: ``[agent_action, adversary_action]`` concatenated.

    For libraries without ``Tuple`` action spaces (Stable-Baselines3, CleanRL-style code).

    >>> import numpy as np
    >>> from rrls.envs import RobustHopper, HopperParamsBound
    >>> from rrls.wrappers import ConcatenateActions, DynamicAdversarial
    >>> game = DynamicAdversarial(RobustHopper(), HopperParamsBound.TWO_DIM.value)
    >>> env = ConcatenateActions(game)
    >>> env.action_space.shape
    (5,)
    """

    def __init__(self, env: gym.Env) -> None:
        super().__init__(env)
        space = env.action_space
        if not isinstance(space, spaces.Tuple) or not all(
            isinstance(s, spaces.Box) for s in space.spaces
        ):
            raise TypeError(f"ConcatenateActions needs a Tuple of Box action space, got {space}")
        self._pair = space
        self._split = int(np.prod(space.spaces[0].shape))
        self.action_space = spaces.Box(
            np.concatenate([s.low.ravel() for s in space.spaces]),
            np.concatenate([s.high.ravel() for s in space.spaces]),
            dtype=np.float32,
        )

    def step(self, action: Any):
        flat = np.asarray(action, dtype=np.float32)
        if flat.shape != self.action_space.shape:
            raise ValueError(f"action must have shape {self.action_space.shape}, got {flat.shape}")
        a, b = self._pair.spaces
        pair = (flat[: self._split].reshape(a.shape), flat[self._split :].reshape(b.shape))
        return self.env.step(pair)


__all__ = ["ConcatenateActions", "ProbabilisticActionRobust"]
