"""Context in the observation: the agent sees where it is in the uncertainty set.

The current values of a set's parameters, normalised to the set (``[-1, 1]`` per axis), are
appended to the observation. The idea is TC-RMDP's "oracle" agent and CARL's visible context;
the scaling is rrls's own: CARL appends the raw values (optionally divided by their mean or
default, ``scale_context_features``), the TC-RMDP oracle sees them normalised to ``[0, 1]``.
TC-RMDP's Oracle protagonist itself is ``rrls.wrappers.tc_rmdp.View("oracle")``.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from rrls.uncertainty import UncertaintySet
from rrls.wrappers._checks import check_names, read_point, refuse_empty
from rrls.wrappers.access import ParamsForwarding


class ContextObservation(ParamsForwarding, gym.utils.RecordConstructorArgs):
    """Append the parameters of ``params_bound``, normalised to the set, to the observation.

    The observation space grows by ``dim`` entries in ``[-1, 1]``; a value outside the set reads
    as the nearest edge. The values are read after each ``reset`` and ``step`` (so under a
    schedule or an adversary they are the parameters of the step just taken). Any parameter in
    the env's ``get_params`` can be context: masses, frictions, forces, disruptor strengths.

    >>> import numpy as np
    >>> from rrls.envs import RobustHopper
    >>> from rrls.wrappers import ContextObservation
    >>> env = ContextObservation(RobustHopper(torsomass=5.0), {"torsomass": (1.0, 5.0)})
    >>> env.observation_space.shape
    (12,)
    >>> obs, _ = env.reset(seed=0)
    >>> float(obs[-1])
    1.0
    """

    def __init__(
        self, env: gym.Env, params_bound: Mapping[str, Sequence[float]] | UncertaintySet
    ) -> None:
        gym.utils.RecordConstructorArgs.__init__(self, params_bound=params_bound)
        super().__init__(env)
        space = env.observation_space
        if not isinstance(space, spaces.Box) or len(space.shape) != 1:
            raise TypeError(f"ContextObservation needs a flat Box observation space, got {space}")
        self.uncertainty_set = UncertaintySet.from_bounds(params_bound)
        refuse_empty(self.uncertainty_set, "ContextObservation", self.env)
        check_names(self.env, self.uncertainty_set)
        d = self.uncertainty_set.dim
        self.observation_space = spaces.Box(
            np.concatenate([space.low, -np.ones(d)]).astype(space.dtype),
            np.concatenate([space.high, np.ones(d)]).astype(space.dtype),
            dtype=space.dtype,
        )

    def context(self) -> np.ndarray:
        """The current parameters of the set, normalised to ``[-1, 1]``."""
        box = self.uncertainty_set
        return np.clip(box.normalize(read_point(self.env, box)), -1.0, 1.0)

    def _with_context(self, obs: np.ndarray) -> np.ndarray:
        return np.concatenate([obs, self.context()]).astype(self.observation_space.dtype)

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        obs, info = self.env.reset(seed=seed, options=options)
        return self._with_context(obs), info

    def step(self, action: Any):
        obs, reward, terminated, truncated, info = self.env.step(action)
        return self._with_context(obs), reward, terminated, truncated, info


__all__ = ["ContextObservation"]
