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
    action to ``[-1, 1]``, maps it linearly onto the bounds, sets those parameters, then steps
    with the agent's action. The agent's reward is unchanged; ``info["adversarial_reward"]`` is
    its negation. Parameters return to the env's nominal values at every reset.

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
        self.adversary_space = spaces.Box(-1.0, 1.0, (self.uncertainty_set.dim,), np.float32)
        self.action_space = spaces.Tuple((env.action_space, self.adversary_space))
        self._set_params = self.env.get_wrapper_attr("set_params")

    def step(self, action: Any):
        agent, adversary = split_pair(action, self.action_space)
        box = self.uncertainty_set
        values = box.denormalize(adversary.astype(np.float64).clip(-1.0, 1.0))
        self._set_params(**dict(zip(box.names, values.tolist())))
        obs, reward, terminated, truncated, info = self.env.step(agent)
        info["adversarial_reward"] = -reward
        return obs, reward, terminated, truncated, info

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        self.env.get_wrapper_attr("reset_params")()
        return self.env.reset(seed=seed, options=options)
