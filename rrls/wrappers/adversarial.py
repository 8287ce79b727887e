"""The adversarial two-player game: an adversary picks the parameters at every step."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from rrls.interface import all_params
from rrls.uncertainty import UncertaintySet
from rrls.wrappers._checks import check_names, read_point, refuse_empty, split_pair
from rrls.wrappers.access import ParamsForwarding


class DynamicAdversarial(ParamsForwarding, gym.utils.RecordConstructorArgs):
    """Zero-sum game over the parameters of ``params_bound`` (paper §4, RARL / M2TD3 setting).

    The action space is ``Tuple(agent_space, Box(-1, 1, (k,)))``. Each step clips the adversary's
    action to ``[-1, 1]``, maps it linearly onto the bounds with the original code's arithmetic
    (``low + ((a + 1) * (high - low)) / 2`` in the action's dtype, so values compare ``==`` with
    the original's), sets those parameters, then steps with the agent's action. The agent's
    reward is unchanged; ``info["adversarial_reward"]`` is its negation. Parameters return to
    the env's nominal values at every reset. ``get_params()`` returns the game's parameters
    (those of ``params_bound``), as the original did; ``get_params(kinds="all")`` all.

    ``rate_limit=L`` is the game of Time-Constrained Robust MDPs (Zouitine et al., NeurIPS 2024):
    the adversary's action is still a target point of the box, but the parameter vector moves
    towards it by at most ``L`` per step in the set's normalised units (``[-1, 1]`` per axis,
    so ``L=2`` allows any jump), coordinate-wise (an L-infinity bound). Each episode starts from
    the parameters in force after ``reset`` (nominal, or ``reset(options=...)``), clipped into
    the box. Coordinates whose target is within ``L`` take the target exactly, so a limit that
    never binds plays exactly the unlimited game. ``info["normalized_params"]`` holds the point
    played. An empty set is refused (the game would be a silent no-op).

    >>> import numpy as np
    >>> from rrls.envs import RobustHopper, HopperParamsBound
    >>> from rrls.wrappers import DynamicAdversarial
    >>> env = DynamicAdversarial(RobustHopper(), HopperParamsBound.ONE_DIM.value)
    >>> _ = env.reset(seed=0)
    >>> _, r, *_, info = env.step((np.zeros(3), np.array([1.0])))
    >>> info["worldfriction"], bool(info["adversarial_reward"] == -r)
    (3.0, True)
    >>> slow = DynamicAdversarial(RobustHopper(), {"worldfriction": (0.1, 3.1)}, rate_limit=0.1)
    >>> _ = slow.reset(seed=0)  # nominal friction 1.0 is -0.4 in normalised units
    >>> *_, info = slow.step((np.zeros(3), np.array([1.0])))  # the target is the upper bound
    >>> round(float(info["normalized_params"][0]), 6), round(info["worldfriction"], 6)
    (-0.3, 1.15)
    """

    def __init__(
        self,
        env: gym.Env,
        params_bound: Mapping[str, Sequence[float]] | UncertaintySet,
        rate_limit: float | None = None,
    ) -> None:
        gym.utils.RecordConstructorArgs.__init__(
            self, params_bound=params_bound, rate_limit=rate_limit
        )
        super().__init__(env)
        self.uncertainty_set = UncertaintySet.from_bounds(params_bound)
        self.params_bound = self.uncertainty_set.as_bounds()
        refuse_empty(self.uncertainty_set, "DynamicAdversarial", self.env)
        check_names(self.env, self.uncertainty_set)
        if rate_limit is not None and (
            isinstance(rate_limit, bool)
            or not isinstance(rate_limit, (int, float, np.integer, np.floating))
            or not np.isfinite(rate_limit)
            or rate_limit < 0
        ):
            raise ValueError(
                f"rate_limit must be a finite number >= 0 (normalised units per step) or None, "
                f"got {rate_limit!r}"
            )
        self.rate_limit = None if rate_limit is None else float(rate_limit)
        self._current: np.ndarray | None = None  # the normalised point in force (rate limit)
        self._step = 0
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
        self._step += 1
        agent, adversary = split_pair(action, self.action_space, self._step)
        params = self.params_of(adversary)
        if self.rate_limit is not None:
            params = self._limited(params)
        self._set_params(**params)
        obs, reward, terminated, truncated, info = self.env.step(agent)
        info["adversarial_reward"] = -reward
        if self.rate_limit is not None:
            info["normalized_params"] = self._current.copy()
        return obs, reward, terminated, truncated, info

    def _limited(self, target: dict[str, float]) -> dict[str, float]:
        """Move from the point in force towards ``target`` by at most ``rate_limit`` per axis."""
        box, limit = self.uncertainty_set, self.rate_limit
        goal = box.normalize([target[n] for n in box.names])
        here = self._current
        delta = goal - here
        free = np.abs(delta) <= limit
        moved = np.where(free, goal, here + np.clip(delta, -limit, limit))
        # axes that reach their target take it exactly (the unlimited game's float32 values)
        values = np.where(free, [target[n] for n in box.names], box.denormalize(moved))
        values = np.clip(values, box.low, box.high)
        self._current = np.where(free, goal, moved)
        return {n: float(v) for n, v in zip(box.names, values)}

    def get_params(self, kinds: Any = None) -> dict[str, float]:
        """The game's parameters: those the adversary controls, at their current values.

        As in the original code, where the parameters nobody set read ``None``; the env's own
        are ``get_params(kinds="all")`` (or ``env.unwrapped.get_params(kinds="all")``).
        """
        if kinds is not None:
            return ParamsForwarding.get_params(self, kinds)
        params = all_params(self.env)
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
        obs, info = self.env.reset(seed=seed, options=options)
        self._step = 0
        if self.rate_limit is not None:
            box = self.uncertainty_set
            now = read_point(self.env, box)
            start = box.clip(now)
            self._current = box.normalize(start)
            if not np.array_equal(start, now):
                self._set_params(**box.to_dict(start))
            info["normalized_params"] = self._current.copy()
        return obs, info
