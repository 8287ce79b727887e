"""Time-Constrained Robust MDPs (Zouitine et al., NeurIPS 2024): the pieces of their game.

Checked against the authors' code, ``SuReLI/TCRMDP`` at commit ``e37cb52``, ``src/tc_mdp.py``
(cited below as ``tc_mdp.py:LINE``) and its training scripts:

* the adversary's action ``a`` in ``[-1, 1]^k`` is a *move*: ``ψ ← clip(ψ + a · radius, low,
  high)`` per coordinate, in raw parameter units (``tc_mdp.py:141-149``); the training scripts
  use ``radius=0.001`` (``main_vanilla_tc_rarl.py:24``), the fixed evaluation adversary
  ``radius=0.1`` (``main_tc_adversary.py:20``);
* each episode starts from a uniform draw in the box (``tc_mdp.py:80-85, 101``);
* the adversary observes ψ, normalised to ``[0, 1]`` per axis, and the state
  (``tc_mdp.py:589-596``), plus the protagonist's action of the step when omniscient, the
  scripts' default (``trainer.py:407-414``, ``main_vanilla_tc_rarl.py:25``);
* the protagonist observes the state (Vanilla), the previous state, the state and the previous
  action (Stacked, ``tc_mdp.py:597-599, 631``) or the state and ψ in ``[0, 1]`` (Oracle,
  ``tc_mdp.py:362-370``).

:class:`View` says what the protagonist sees; :class:`ProtagonistObservation` shows it in a
one-player env (the static evaluation of a Stacked or Oracle protagonist, the authors'
``EvalStaticStacked``/``EvalStaticOracle``, ``tc_mdp.py:747-932``).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from rrls.uncertainty import UncertaintySet
from rrls.wrappers._checks import check_names, read_point
from rrls.wrappers.access import ParamsForwarding

#: the protagonist variants of the TC-RMDP paper (§5: Vanilla, Stacked, Oracle)
OBSERVE = ("vanilla", "stacked", "oracle")
#: the most states (and actions) a Stacked protagonist may keep: its observation grows with it
MAX_HISTORY = 10_000
#: the rate-limited games: ``tc`` (the authors', default), ``target`` (rrls's earlier one)
RATE_GAMES = ("tc", "target")


def unit_psi(box: UncertaintySet, point: np.ndarray) -> np.ndarray:
    """ψ as the authors normalise it, ``(ψ - low) / (high - low)`` per axis
    (``tc_mdp.py:589-593``); a degenerate axis reads 0. Not clipped: a point outside the box
    (a nominal point above it) reads outside ``[0, 1]``, as in ``tc_mdp.py:798-803``."""
    span = box.high - box.low
    safe = np.where(span > 0, span, 1.0)
    return np.where(span > 0, (np.asarray(point, dtype=np.float64) - box.low) / safe, 0.0)


def tc_move(box: UncertaintySet, psi: np.ndarray, action: np.ndarray, radius: float) -> np.ndarray:
    """The authors' move, ``clip(ψ + a · radius, low, high)`` per coordinate in raw units
    (``tc_mdp.py:145-148``), in float64 with ``a`` clipped to the action box ``[-1, 1]``."""
    a = np.clip(np.asarray(action, dtype=np.float64), -1.0, 1.0)
    return np.clip(psi + a * radius, box.low, box.high)


@dataclass(frozen=True)
class View:
    """What the protagonist observes: ``vanilla`` (``s``), ``stacked`` (the last ``history``
    states, ``s``, then the last ``history`` actions; the paper's ``history=1`` is
    ``[s', s, a']``) or ``oracle`` (``s`` then ψ of ``box`` in ``[0, 1]``).

    >>> View("stacked").dim(11, 3), View("oracle", box=UncertaintySet.from_bounds(
    ...     {"torsomass": (1.0, 5.0)})).dim(11, 3)
    (25, 12)
    """

    observe: str = "vanilla"
    history: int = 1
    box: UncertaintySet | None = None

    def __post_init__(self) -> None:
        if self.observe not in OBSERVE:
            raise ValueError(f"observe must be one of {', '.join(OBSERVE)}, got {self.observe!r}")
        h = self.history
        if isinstance(h, bool) or not isinstance(h, (int, np.integer)) or h < 1:
            raise ValueError(f"history must be an integer >= 1 (states kept), got {h!r}")
        if h > MAX_HISTORY:
            raise ValueError(f"history must be at most {MAX_HISTORY:,} (states kept), got {h!r}")
        if self.observe == "oracle" and (self.box is None or self.box.dim == 0):
            raise ValueError("observe='oracle' needs the uncertainty set whose ψ it shows")

    @property
    def vanilla(self) -> bool:
        return self.observe == "vanilla"

    def dim(self, n_obs: int, n_act: int) -> int:
        """The protagonist's observation size for states of ``n_obs`` and actions of ``n_act``."""
        if self.observe == "stacked":
            return (self.history + 1) * n_obs + self.history * n_act
        if self.observe == "oracle":
            return n_obs + self.box.dim
        return n_obs

    def to_metadata(self) -> dict[str, Any]:
        """What a saved policy records, so its evaluations show it the same observations."""
        out: dict[str, Any] = {"observe": self.observe}
        if self.observe == "stacked":
            out["history"] = int(self.history)
        if self.observe == "oracle":
            out["psi_bounds"] = self.box.as_bounds()
        return out

    @classmethod
    def from_metadata(cls, meta: dict[str, Any] | None) -> View | None:
        """The view a policy's metadata records; ``None`` for a plain (vanilla) policy."""
        meta = meta or {}
        observe = meta.get("observe") or "vanilla"
        if observe == "vanilla":
            return None
        bounds = meta.get("psi_bounds")
        box = None if bounds is None else UncertaintySet.from_bounds(bounds)
        return cls(observe, int(meta.get("history") or 1), box)


class ViewState:
    """One episode's protagonist observations (the Stacked variant's history)."""

    def __init__(self, view: View, n_obs: int, n_act: int) -> None:
        self.view, self.n_act = view, n_act
        self._states: list[np.ndarray] = []
        self._actions: list[np.ndarray] = []

    def reset(self, s: np.ndarray, psi_unit: np.ndarray | None) -> np.ndarray:
        """At reset the past states are ``s`` and the past actions zeros (``tc_mdp.py:597-598``)."""
        k = self.view.history
        self._states = [np.asarray(s, dtype=np.float64)] * (k + 1)
        self._actions = [np.zeros(self.n_act)] * k
        return self._show(psi_unit)

    def step(self, s: np.ndarray, action: Any, psi_unit: np.ndarray | None) -> np.ndarray:
        if self.view.observe == "stacked":
            self._states = [*self._states[1:], np.asarray(s, dtype=np.float64)]
            a = np.asarray(action, dtype=np.float64).reshape(self.n_act)
            self._actions = [*self._actions[1:], a]
        else:
            self._states = [np.asarray(s, dtype=np.float64)]
        return self._show(psi_unit)

    def _show(self, psi_unit: np.ndarray | None) -> np.ndarray:
        if self.view.observe == "stacked":
            return np.concatenate([*self._states, *self._actions])
        if self.view.observe == "oracle":
            return np.concatenate([self._states[-1], psi_unit])
        return self._states[-1].copy()


class ProtagonistObservation(ParamsForwarding, gym.utils.RecordConstructorArgs):
    """A one-player env seen as a Stacked or Oracle protagonist sees it (``view``).

    For evaluating such a protagonist on static parameters, as the authors' ``EvalStaticStacked``
    and ``EvalStaticOracle`` do (``tc_mdp.py:747-932``); ψ is read from the env after each reset
    and step, normalised to ``view.box`` like in the game.

    >>> from rrls.envs import RobustHopper
    >>> box = UncertaintySet.from_bounds({"torsomass": (1.0, 5.0)})
    >>> env = ProtagonistObservation(RobustHopper(torsomass=2.0), View("oracle", box=box))
    >>> obs, _ = env.reset(seed=0)
    >>> obs.shape, float(obs[-1])
    ((12,), 0.25)
    """

    def __init__(self, env: gym.Env, view: View) -> None:
        gym.utils.RecordConstructorArgs.__init__(self, view=view)
        super().__init__(env)
        space, act = env.observation_space, env.action_space
        if not isinstance(space, spaces.Box) or len(space.shape) != 1:
            raise TypeError(f"ProtagonistObservation needs a flat Box observation, got {space}")
        if not isinstance(act, spaces.Box) or len(act.shape) != 1:
            raise TypeError(f"ProtagonistObservation needs a flat Box action space, got {act}")
        if not isinstance(view, View):
            raise TypeError(f"view must be a View, got {type(view).__name__}")
        if view.box is not None:
            check_names(self.env, view.box)
        self.view = view
        self._state = ViewState(view, space.shape[0], act.shape[0])
        self.observation_space = spaces.Box(
            -np.inf, np.inf, (view.dim(space.shape[0], act.shape[0]),), np.float64
        )

    def _psi(self) -> np.ndarray | None:
        box = self.view.box
        return None if self.view.observe != "oracle" else unit_psi(box, read_point(self.env, box))

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        obs, info = self.env.reset(seed=seed, options=options)
        return self._state.reset(obs, self._psi()), info

    def step(self, action: Any):
        obs, reward, terminated, truncated, info = self.env.step(action)
        return self._state.step(obs, action, self._psi()), reward, terminated, truncated, info


__all__ = [
    "MAX_HISTORY",
    "OBSERVE",
    "ProtagonistObservation",
    "RATE_GAMES",
    "tc_move",
    "unit_psi",
    "View",
    "ViewState",
]
