"""The adversarial two-player game: an adversary picks the parameters at every step."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from gymnasium.utils import seeding

from rrls.interface import all_params
from rrls.uncertainty import UncertaintySet
from rrls.wrappers._checks import check_names, read_point, refuse_empty, split_pair
from rrls.wrappers.access import ParamsForwarding
from rrls.wrappers.tc_rmdp import RATE_GAMES, View, ViewState, tc_move, unit_psi


class DynamicAdversarial(ParamsForwarding, gym.utils.RecordConstructorArgs):
    """Zero-sum game over the parameters of ``params_bound`` (paper §4, RARL / M2TD3 setting).

    The action space is ``Tuple(agent_space, Box(-1, 1, (k,)))``. Each step clips the adversary's
    action to ``[-1, 1]``, maps it linearly onto the bounds with the original code's arithmetic
    (``low + ((a + 1) * (high - low)) / 2`` in the action's dtype, so values compare ``==`` with
    the original's), sets those parameters, then steps with the agent's action. The agent's
    reward is unchanged; ``info["adversarial_reward"]`` is its negation. Parameters return to
    the env's nominal values at every reset. ``get_params()`` returns the game's parameters
    (those of ``params_bound``), as the original did; ``get_params(kinds="all")`` all.

    ``rate_limit=r`` plays Time-Constrained Robust MDPs (Zouitine et al., NeurIPS 2024) as the
    authors' code does (:mod:`rrls.wrappers.tc_rmdp`, ``rate_game="tc"``): the adversary's
    action ``a`` is a move, ``ψ ← clip(ψ + a · r, low, high)`` per coordinate in *raw*
    parameter units (the authors train with ``r = 0.001``); each episode starts from a uniform
    draw in the box, from the env's generator that ``reset(seed=...)`` seeds (parameters named
    in ``reset(options=...)`` fix their coordinate instead). The observation is flat, the
    protagonist's part then the adversary's: ``view`` (``observe``/``history``: Vanilla ``s``,
    Stacked, Oracle ``[s, ψ01]``) then ``[ψ01, s]``, ψ01 being ψ normalised to ``[0, 1]``;
    ``views`` holds their index ranges. ``info["psi"]`` is ψ in raw units.
    ``rate_game="target"`` is rrls's earlier game: the action is a target point, the
    parameters move towards it by at most ``r`` per step in ``[-1, 1]``-normalised units,
    episodes start at the nominal point clipped into the box, both players see ``s``.
    An empty set is refused (the game would be a silent no-op).

    >>> import numpy as np
    >>> from rrls.envs import RobustHopper, HopperParamsBound
    >>> from rrls.wrappers import DynamicAdversarial
    >>> env = DynamicAdversarial(RobustHopper(), HopperParamsBound.ONE_DIM.value)
    >>> _ = env.reset(seed=0)
    >>> _, r, *_, info = env.step((np.zeros(3), np.array([1.0])))
    >>> info["worldfriction"], bool(info["adversarial_reward"] == -r)
    (3.0, True)
    >>> tc = DynamicAdversarial(RobustHopper(), {"worldfriction": (0.1, 3.1)}, rate_limit=0.1)
    >>> _ = tc.reset(seed=0, options={"worldfriction": 1.0})  # start at 1.0 (default: uniform)
    >>> obs, *_, info = tc.step((np.zeros(3), np.array([1.0])))  # +1 x 0.1 raw units
    >>> round(float(info["psi"][0]), 6), tc.views, round(float(obs[11]), 6)  # ψ01 = 1.0/3
    (1.1, ((0, 11), (11, 23)), 0.333333)
    """

    def __init__(
        self,
        env: gym.Env,
        params_bound: Mapping[str, Sequence[float]] | UncertaintySet,
        rate_limit: float | None = None,
        *,
        rate_game: str = "tc",
        observe: str = "vanilla",
        history: int = 1,
    ) -> None:
        gym.utils.RecordConstructorArgs.__init__(
            self,
            params_bound=params_bound,
            rate_limit=rate_limit,
            rate_game=rate_game,
            observe=observe,
            history=history,
        )
        super().__init__(env)
        self.uncertainty_set = box = UncertaintySet.from_bounds(params_bound)
        self.params_bound = box.as_bounds()
        refuse_empty(box, "DynamicAdversarial", self.env)
        check_names(self.env, box)
        if rate_game not in RATE_GAMES:
            raise ValueError(f"rate_game must be one of {', '.join(RATE_GAMES)}, got {rate_game!r}")
        units = "raw parameter units" if rate_game == "tc" else "normalised units"
        if rate_limit is not None and (
            isinstance(rate_limit, bool)
            or not isinstance(rate_limit, (int, float, np.integer, np.floating))
            or not np.isfinite(rate_limit)
            or rate_limit < 0
        ):
            raise ValueError(
                f"rate_limit must be a finite number >= 0 ({units} per step) or None, "
                f"got {rate_limit!r}"
            )
        self.rate_limit = None if rate_limit is None else float(rate_limit)
        self.rate_game = rate_game
        self.tc = self.rate_limit is not None and rate_game == "tc"
        self.view = View(observe, history, box)  # validates observe and history
        if not self.view.vanilla and not self.tc:
            raise ValueError(
                f"observe={observe!r} is a protagonist of the TC-RMDP game: give rate_limit "
                "(with rate_game='tc')"
            )
        self._current: np.ndarray | None = None  # target game: the normalised point in force
        self._psi: np.ndarray | None = None  # TC game: the raw point in force
        self._step = 0
        self._bounds = [
            (name, float(lo), float(hi)) for name, lo, hi in zip(box.names, box.low, box.high)
        ]
        self.adversary_space = spaces.Box(-1.0, 1.0, (box.dim,), np.float32)
        self.action_space = spaces.Tuple((env.action_space, self.adversary_space))
        self._set_params = self.env.get_wrapper_attr("set_params")
        n = env.observation_space.shape[0]
        if self.tc:
            m = env.action_space.shape[0]
            p = self.view.dim(n, m)
            self._seen = ViewState(self.view, n, m)
            self.views = ((0, p), (p, p + box.dim + n))
            self.observation_space = spaces.Box(-np.inf, np.inf, (p + box.dim + n,), np.float64)
        else:  # both players see the env's observation
            self.views = ((0, n), (0, n))

    def step(self, action: Any):
        self._step += 1
        agent, adversary = split_pair(action, self.action_space, self._step)
        if self.tc:
            self._psi = tc_move(self.uncertainty_set, self._psi, adversary, self.rate_limit)
            params = self.uncertainty_set.to_dict(self._psi)
        else:
            params = self.params_of(adversary)
            if self.rate_limit is not None:
                params = self._limited(params)
        self._set_params(**params)  # before the agent's action, as tc_mdp.py:119-122
        obs, reward, terminated, truncated, info = self.env.step(agent)
        info["adversarial_reward"] = -reward
        if self.tc:
            unit = unit_psi(self.uncertainty_set, self._psi)
            obs = self._joint(self._seen.step(obs, agent, unit), unit, obs)
            info["psi"] = self._psi.copy()
        elif self.rate_limit is not None:
            info["normalized_params"] = self._current.copy()
        return obs, reward, terminated, truncated, info

    def _joint(self, protagonist: np.ndarray, unit: np.ndarray, s: np.ndarray) -> np.ndarray:
        """The flat observation: the protagonist's view, then the adversary's ``[ψ01, s]``."""
        return np.concatenate([protagonist, unit, np.asarray(s, dtype=np.float64)])

    def _limited(self, target: dict[str, float]) -> dict[str, float]:
        """Target game: move towards ``target`` by at most ``rate_limit`` per normalised axis."""
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
        self._step = 0
        if self.tc:
            return self._tc_reset(seed, options)
        obs, info = self.env.reset(seed=seed, options=options)
        if self.rate_limit is not None:
            box = self.uncertainty_set
            now = read_point(self.env, box)
            start = box.clip(now)
            self._current = box.normalize(start)
            if not np.array_equal(start, now):
                self._set_params(**box.to_dict(start))
            info["normalized_params"] = self._current.copy()
        return obs, info

    def _tc_reset(self, seed: int | None, options: dict[str, Any] | None) -> tuple:
        """A uniform start in the box (``tc_mdp.py:80-85, 101``), drawn from the env's generator
        once ``seed`` has seeded it, before the episode's initial state (as DomainRandomization)."""
        if options is not None and not isinstance(options, dict):
            raise ValueError(f"options must be a dict of parameters, got {type(options).__name__}")
        box, options = self.uncertainty_set, dict(options or {})
        fixed = {n: options.pop(n) for n in box.names if n in options}
        for name, value in fixed.items():
            i = box.names.index(name)
            if not (
                isinstance(value, (int, float, np.integer, np.floating))
                and not isinstance(value, bool)
                and box.low[i] <= value <= box.high[i]
            ):
                raise ValueError(
                    f"reset option {name}={value!r} must be a number in the game's box "
                    f"[{box.low[i]:g}, {box.high[i]:g}]"
                )
        previous = self.env.np_random if seed is not None else None
        if seed is not None:
            self.env.np_random, _ = seeding.np_random(seed)
        rng = self.env.np_random
        state = rng.bit_generator.state
        try:
            start = rng.uniform(box.low, box.high)
            for name, value in fixed.items():
                start[box.names.index(name)] = float(value)
            obs, info = self.env.reset(options={**options, **box.to_dict(start)})
        except Exception:
            rng.bit_generator.state = state  # a refused reset changes nothing
            if previous is not None:
                self.env.np_random = previous
            raise
        self._psi = start
        unit = unit_psi(box, start)
        info["psi"] = start.copy()
        return self._joint(self._seen.reset(obs, unit), unit, obs), info


__all__ = ["DynamicAdversarial"]
