"""The two-player games of dynamic evaluation (paper Table 6): which env both players play, and
how each sees it.

The adversary acts every step — choosing the physical parameters (``DynamicAdversarial``, over a
parameter set or the RARL force set) or perturbing the action (``ProbabilisticActionRobust``,
NR-MDP/PR-MDP). A :class:`Game` is the frozen description the rollout engine builds its envs
from (one per lane, cached like the static evaluation's); :class:`TwoPlayers` calls both
policies on a batch of observations, each on its part (``env.views`` in the TC-RMDP game; the
omniscient adversary also sees the protagonist's action of the step).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from rrls.physics import PAPER

__all__ = ["Game", "TwoPlayers", "dynamic_env_id", "make_dynamic_env"]


def dynamic_env_id(task: str, game: str = "adversarial", uncertainty: str = "3d") -> str:
    """The registered id of ``task``'s two-player game.

    ``game="adversarial"`` with ``uncertainty`` in ``1d/2d/3d`` (parameters) or ``rarl`` (forces);
    ``game="nr"`` / ``"pr"``: the action-robust game (NR-MDP / PR-MDP).
    """
    from rrls.envs import resolve

    if game == "adversarial":
        if not isinstance(uncertainty, str):
            raise ValueError("the registered adversarial games take a set name (1d, 2d, 3d, rarl)")
        resolved = resolve(task, uncertainty)
        if resolved.is_nominal:
            raise ValueError("the nominal model has no parameters for an adversary to play")
        name = "forces" if resolved.family == "force" else resolved.name
        return f"rrls/robust-{resolved.task}-adversarial-{name}-v0"
    key = resolve(task, "nominal").task
    if game in ("nr", "pr"):
        return f"rrls/probabilistic-action-robust-{key}-v0"
    raise ValueError(f"unknown game {game!r}; valid: adversarial, nr, pr")


def make_dynamic_env(
    task: str,
    game: str = "adversarial",
    uncertainty: str | Any = "3d",
    alpha: float = 0.1,
    rate_limit: float | None = None,
    context: bool = False,
    paper: bool = False,
    *,
    rate_game: str = "tc",
    observe: str = "vanilla",
    history: int = 1,
) -> Any:
    """The two-player env: the registered id, or ``ProbabilisticActionRobust`` with ``alpha``.

    For the parameter game, ``rate_limit=r`` is TC-RMDP's game as its authors play it
    (``DynamicAdversarial``, ``rate_game="tc"``): the adversary moves ψ by ``a · r`` per step
    in raw units, episodes start uniformly in the box, the flat observation holds the
    protagonist's view (``observe``: vanilla, stacked with ``history``, oracle) then the
    adversary's ``[ψ01, s]`` (``env.views``). ``rate_game="target"``: rrls's earlier game
    (``r`` in normalised units towards a target point). ``context=True`` appends the
    parameters in force, normalised to ``[-1, 1]``, to the shared observation of the other
    parameter games (in the TC game the Oracle protagonist is ``observe="oracle"``);
    ``uncertainty`` may then also be an ``UncertaintySet``. This is the env both training
    (RARL ``--rate-limit``) and :func:`evaluate_dynamic` play. ``paper=True``: the paper's
    physics.

    >>> env = make_dynamic_env("hopper", uncertainty="2d", rate_limit=0.01, observe="oracle")
    >>> env.observation_space.shape, env.get_wrapper_attr("views")
    ((26,), ((0, 13), (13, 26)))
    """
    import gymnasium as gym

    kw = {"paper": True} if paper else {}
    tc = rate_limit is not None and rate_game == "tc"
    if game != "adversarial" and (rate_limit is not None or context or observe != "vanilla"):
        raise ValueError(
            "rate_limit, observe and context apply to the parameter game (game='adversarial')"
        )
    if tc and context:
        raise ValueError(
            "context=True is not part of the TC-RMDP game: its Oracle protagonist is "
            "observe='oracle' (ψ in [0, 1]); the adversary always sees ψ"
        )
    if game == "adversarial" and (
        rate_limit is not None
        or context
        or observe != "vanilla"
        or not isinstance(uncertainty, str)
    ):
        from rrls.envs import resolve
        from rrls.wrappers import ContextObservation, DynamicAdversarial

        resolved = resolve(task, uncertainty)
        if resolved.is_nominal:
            raise ValueError("the nominal model has no parameters for an adversary to play")
        base = gym.make(f"rrls/{resolved.family}-{resolved.task}-v0", **kw)
        env = DynamicAdversarial(
            base,
            resolved.box,
            rate_limit=rate_limit,
            rate_game=rate_game,
            observe=observe,
            history=history,
        )
        return ContextObservation(env, resolved.box) if context else env
    env_id = dynamic_env_id(task, game, uncertainty)
    if game == "adversarial":
        return gym.make(env_id, **kw)
    from rrls.tasks import get_task
    from rrls.wrappers import ProbabilisticActionRobust

    base = gym.make(f"rrls/robust-{get_task(task).key}-v0", **kw)
    return ProbabilisticActionRobust(base, alpha, game)


@dataclass(frozen=True)
class Game:
    """One two-player game, as :func:`make_dynamic_env` builds it; hashable, so the engine's env
    cache keys on it. ``omniscient``: the TC-RMDP adversary also sees the protagonist's action."""

    task: str
    game: str = "adversarial"
    uncertainty: Any = "3d"  # a set's name, or an UncertaintySet (the context/rate games)
    alpha: float = 0.1
    rate_limit: float | None = None
    context: bool = False
    paper: bool = False
    rate_game: str = "tc"
    observe: str = "vanilla"
    history: int = 1
    omniscient: bool = True

    @property
    def tc(self) -> bool:
        """TC-RMDP's game: each player sees its own part of the flat observation."""
        return self.game == "adversarial" and self.rate_limit is not None and self.rate_game == "tc"

    def make_env(self) -> Any:
        return make_dynamic_env(
            self.task,
            self.game,
            self.uncertainty,
            self.alpha,
            self.rate_limit,
            self.context,
            self.paper,
            rate_game=self.rate_game,
            observe=self.observe,
            history=self.history,
        )

    @property
    def env_id(self) -> str:
        """The registered id, or a description of the game (``[paper]`` on the paper's physics)."""
        if (
            self.rate_limit is None
            and not self.context
            and self.observe == "vanilla"
            and isinstance(self.uncertainty, str)
        ):
            env_id = dynamic_env_id(self.task, self.game, self.uncertainty)
        elif self.tc:
            stacked = self.observe == "stacked"
            shown = f"stacked, history={self.history}" if stacked else self.observe
            env_id = (
                f"{self.task}-adversarial ({self.uncertainty}, rate_limit={self.rate_limit}, "
                f"rate_game=tc, observe={shown}, omniscient={bool(self.omniscient)})"
            )
        else:
            target = "" if self.rate_limit is None else ", rate_game=target"
            env_id = (
                f"{self.task}-adversarial ({self.uncertainty}, rate_limit={self.rate_limit}"
                f"{target}, context={self.context})"
            )
        return env_id + (f" [{PAPER}]" if self.paper else "")


class TwoPlayers:
    """Both policies on a batch of the game's observations: the protagonist on its view, then
    the adversary on its own (with the protagonist's actions when omniscient,
    ``trainer.py:407-414`` of the TC-RMDP authors' code)."""

    def __init__(self, protagonist: Any, adversary: Any, game: Game, views: Any = None) -> None:
        self.protagonist, self.adversary = protagonist, adversary
        (self.p0, self.p1), (self.a0, self.a1) = views if game.tc else ((0, None), (0, None))
        self.omniscient = game.tc and game.omniscient

    def protagonist_actions(self, obs: np.ndarray) -> Any:
        return self.protagonist(obs[:, self.p0 : self.p1])

    def adversary_actions(self, obs: np.ndarray, agent: np.ndarray) -> Any:
        seen = obs[:, self.a0 : self.a1]
        if self.omniscient:
            seen = np.concatenate([seen, agent], axis=1)
        return self.adversary(seen)
