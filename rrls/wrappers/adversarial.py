"""The adversarial two-player game: an adversary picks the parameters at every step."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from rrls.uncertainty import UncertaintySet
from rrls.wrappers._checks import check_names, split_pair
from rrls.wrappers.access import ParamsForwarding


class DynamicAdversarial(ParamsForwarding, gym.utils.RecordConstructorArgs):
    """Zero-sum game over the parameters of ``params_bound`` (paper §4, RARL / M2TD3 setting).

    The action space is ``Tuple(agent_space, Box(-1, 1, (k,)))``. Each step clips the adversary's
    action to ``[-1, 1]``, maps it linearly onto the bounds with the original code's arithmetic
    (``low + ((a + 1) * (high - low)) / 2`` in the action's dtype, so values compare ``==`` with
    the original's), sets those parameters, then steps with the agent's action. The agent's
    reward is unchanged; ``info["adversarial_reward"]`` is its negation. Parameters return to
    the env's nominal values at every reset. ``get_params()`` returns the game's parameters
    (those of ``params_bound``), as the original did; ``env.unwrapped.get_params()`` all.

    >>> import numpy as np
    >>> from rrls.envs import RobustHopper, HopperParamsBound
    >>> from rrls.wrappers import DynamicAdversarial
    >>> env = DynamicAdversarial(RobustHopper(), HopperParamsBound.ONE_DIM.value)
    >>> _ = env.reset(seed=0)
    >>> _, r, *_, info = env.step((np.zeros(3), np.array([1.0])))
    >>> info["worldfriction"], bool(info["adversarial_reward"] == -r)
    (3.0, True)
    """

    def __init__(
        self, env: gym.Env, params_bound: Mapping[str, Sequence[float]] | UncertaintySet
    ) -> None:
        gym.utils.RecordConstructorArgs.__init__(self, params_bound=params_bound)
        super().__init__(env)
        self.uncertainty_set = UncertaintySet.from_bounds(params_bound)
        self.params_bound = self.uncertainty_set.as_bounds()
        check_names(self.env, self.uncertainty_set)
        self._bounds = [
            (name, float(lo), float(hi))
            for name, lo, hi in zip(
                self.uncertainty_set.names, self.uncertainty_set.low, self.uncertainty_set.high
            )
        ]
        self.adversary_space = spaces.Box(-1.0, 1.0, (self.uncertainty_set.dim,), np.float32)
        self.action_space = spaces.Tuple((env.action_space, self.adversary_space))
        self._set_params = self.env.get_wrapper_attr("set_params")

    def step(self, action: Any):
        agent, adversary = split_pair(action, self.action_space)
        self._set_params(**self.params_of(adversary))
        obs, reward, terminated, truncated, info = self.env.step(agent)
        info["adversarial_reward"] = -reward
        return obs, reward, terminated, truncated, info

    def get_params(self) -> dict[str, float]:
        """The game's parameters: those the adversary controls, at their current values.

        As in the original code, where the parameters nobody set read ``None``; every parameter
        of the env is ``env.unwrapped.get_params()``.
        """
        params = self.env.get_wrapper_attr("get_params")()
        return {name: params[name] for name, _, _ in self._bounds if name in params}

    def params_of(self, adversary_action: Any) -> dict[str, float]:
        """The parameters an adversary action sets: the original code's arithmetic, in the
        action's dtype (float32), after clipping to ``[-1, 1]``."""
        z = np.asarray(adversary_action, dtype=self.adversary_space.dtype).clip(-1, 1)
        return {
            name: lo + ((v - (-1)) * (hi - lo)) / 2 for (name, lo, hi), v in zip(self._bounds, z)
        }

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        self.env.get_wrapper_attr("reset_params")()
        return self.env.reset(seed=seed, options=options)
