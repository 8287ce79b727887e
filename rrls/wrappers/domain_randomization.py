"""Domain randomization: new physical parameters at every episode (paper §4)."""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium.utils import seeding

from rrls.uncertainty import UncertaintySet
from rrls.wrappers._checks import check_finite_action, check_names, refuse_empty
from rrls.wrappers.access import ParamsForwarding

RandomizeFn = Callable[[UncertaintySet, np.random.Generator], Mapping[str, float]]


class DomainRandomization(ParamsForwarding, gym.utils.RecordConstructorArgs):
    """Draw the parameters of ``params_bound`` anew at each ``reset``.

    Draws come from the env's own generator (``env.np_random``), which ``reset(seed=...)`` seeds
    first, so a seed fixes the whole sequence of episodes: parameters and initial states.
    ``randomize_fn(uncertainty_set, rng) -> {name: value}`` replaces the uniform draw.
    Parameters given in ``reset(options=...)`` win over the draw. ``info["randomized_params"]``
    holds the episode's draw. An empty set (nothing to randomise) and NaN/inf actions are
    refused with a one-line error.

    >>> import gymnasium as gym
    >>> from rrls.envs import RobustHopper, HopperParamsBound
    >>> from rrls.wrappers import DomainRandomization
    >>> env = DomainRandomization(RobustHopper(), HopperParamsBound.TWO_DIM.value)
    >>> _, info = env.reset(seed=0)
    >>> 0.1 <= info["torsomass"] <= 3.0
    True
    """

    def __init__(
        self,
        env: gym.Env,
        params_bound: Mapping[str, Sequence[float]] | UncertaintySet,
        randomize_fn: RandomizeFn | None = None,
    ) -> None:
        gym.utils.RecordConstructorArgs.__init__(self, params_bound=params_bound)
        super().__init__(env)
        self.uncertainty_set = UncertaintySet.from_bounds(params_bound)
        self.params_bound = self.uncertainty_set.as_bounds()
        self.randomize_fn = randomize_fn
        refuse_empty(self.uncertainty_set, "DomainRandomization", self.env)
        check_names(self.env, self.uncertainty_set)
        self._step = 0

    def step(self, action: Any):
        self._step += 1
        check_finite_action(action, self._step)
        return self.env.step(action)

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        if options is not None and not isinstance(options, dict):
            raise ValueError(f"options must be a dict of parameters, got {type(options).__name__}")
        previous = self.env.np_random if seed is not None else None
        if seed is not None:
            self.env.np_random, _ = seeding.np_random(seed)
        rng = self.env.np_random
        state = rng.bit_generator.state
        try:
            if self.randomize_fn is None:
                params = self.uncertainty_set.sample(rng)
            else:
                params = dict(self.randomize_fn(self.uncertainty_set, rng))
            obs, info = self.env.reset(options={**params, **(options or {})})
        except Exception:
            # a refused reset changes nothing: not the generator, not the next episode's draw
            rng.bit_generator.state = state
            if previous is not None:
                self.env.np_random = previous
            raise
        info["randomized_params"] = params
        self._step = 0
        return obs, info


__all__ = ["DomainRandomization", "RandomizeFn"]
