"""Dynamic evaluation (paper Table 6): a protagonist against a trained adversary, step by step.

The adversary acts every step — choosing the physical parameters (``DynamicAdversarial``, over a
parameter set or the RARL force set) or perturbing the action (``ProbabilisticActionRobust``,
NR-MDP/PR-MDP). Episodes run in lockstep (both policies called once per step on the batch);
each episode ``e`` starts from ``reset(seed=seeds[e])``, so a row equals the one-episode loop
``env.reset(seed=seed)`` then ``env.step((protagonist(obs[None])[0], adversary(obs[None])[0]))``
on ``make_dynamic_env(...)`` (in the TC-RMDP game each player on its part of ``obs``,
``env.views``, the omniscient adversary also on the protagonist's action).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from rrls.physics import PAPER, is_paper


@dataclass
class DynamicResult:
    """Per-episode table (``episode``, ``seed``, ``return``, ``length``) and mean ± std return."""

    env_id: str
    episodes: Any  # pandas.DataFrame

    @property
    def mean(self) -> float:
        return float(self.episodes["return"].mean())

    @property
    def std(self) -> float:
        return float(self.episodes["return"].std(ddof=0))

    def __repr__(self) -> str:
        return (
            f"DynamicResult({self.env_id}: {self.mean:.2f} ± {self.std:.2f}, "
            f"{len(self.episodes)} episodes)"
        )


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


def evaluate_dynamic(
    protagonist: Any,
    adversary: Any,
    task: str,
    game: str = "adversarial",
    uncertainty: str = "3d",
    episodes: int = 10,
    seed: int = 0,
    alpha: float = 0.1,
    batch_size: int = 64,
    rate_limit: float | None = None,
    context: bool = False,
    paper: bool = False,
    *,
    rate_game: str = "tc",
    observe: str = "vanilla",
    history: int = 1,
    omniscient: bool = True,
) -> DynamicResult:
    """Mean ± std return of ``protagonist`` while ``adversary`` plays the game every step.

    Both are policies ``obs[B, obs_dim] -> actions``: the adversary's actions live in its own
    space (``[-1, 1]^k`` for the parameter game, the agent's action box for NR/PR-MDP).
    ``rate_limit``, ``rate_game``, ``observe``, ``history`` and ``context``: see
    :func:`make_dynamic_env`. In the TC-RMDP game each player gets its part of the flat
    observation, and an ``omniscient`` adversary (the authors' default) also the protagonist's
    action of the step: ``adversary([ψ01, s, a])``. ``paper=True``: on the paper's physics
    (``env_id`` then ends in ``[paper]``).
    """
    import pandas as pd

    from rrls.evaluation.lanes import episode_seeds
    from rrls.evaluation.policies import as_policy

    _check_arguments(episodes, batch_size, history, seed, alpha, rate_limit)
    tc = game == "adversarial" and rate_limit is not None and rate_game == "tc"
    extras = {
        "rate_limit": rate_limit,
        "context": context,
        "rate_game": rate_game,
        "observe": observe,
        "history": history,
    }
    if rate_limit is None and not context and observe == "vanilla" and isinstance(uncertainty, str):
        env_id = dynamic_env_id(task, game, uncertainty)
    elif tc:
        shown = f"stacked, history={history}" if observe == "stacked" else observe
        env_id = (
            f"{task}-adversarial ({uncertainty}, rate_limit={rate_limit}, rate_game=tc, "
            f"observe={shown}, omniscient={bool(omniscient)})"
        )
    else:
        target = "" if rate_limit is None else ", rate_game=target"
        env_id = (
            f"{task}-adversarial ({uncertainty}, rate_limit={rate_limit}{target}, "
            f"context={context})"
        )
    if paper:
        env_id += f" [{PAPER}]"
    extras["paper"] = paper
    protagonist, adversary = as_policy(protagonist), as_policy(adversary)
    seeds = episode_seeds(seed, 1, episodes)[0]
    n_lanes = max(1, min(batch_size, episodes))
    envs = [make_dynamic_env(task, game, uncertainty, alpha, **extras) for _ in range(n_lanes)]
    (p0, p1), (a0, a1) = envs[0].get_wrapper_attr("views") if tc else ((0, None), (0, None))
    returns, lengths = np.zeros(episodes), np.zeros(episodes, dtype=np.int64)
    queue = iter(range(episodes))
    lane_ep = np.full(n_lanes, -1)
    obs: list[np.ndarray | None] = [None] * n_lanes

    def start(lane: int) -> None:
        e = next(queue, -1)
        lane_ep[lane] = e
        if e >= 0:
            obs[lane], _ = envs[lane].reset(seed=int(seeds[e]))

    for lane in range(n_lanes):
        start(lane)
    while (lane_ep >= 0).any():
        live = np.flatnonzero(lane_ep >= 0)
        batch = np.stack([obs[lane] for lane in live])
        agent = _actions(protagonist(batch[:, p0:p1]), "protagonist", len(live))
        seen = batch[:, a0:a1]
        if tc and omniscient:  # the authors' omniscient adversary (trainer.py:407-414)
            seen = np.concatenate([seen, agent], axis=1)
        adv = _actions(adversary(seen), "adversary", len(live))
        for j, lane in enumerate(live):
            e = lane_ep[lane]
            obs[lane], reward, terminated, truncated, _ = envs[lane].step((agent[j], adv[j]))
            returns[e] += reward
            lengths[e] += 1
            if terminated or truncated:
                start(lane)
    frame = pd.DataFrame(
        {
            "episode": np.arange(episodes),
            "seed": seeds.astype(np.int64),
            "return": returns,
            "length": lengths,
        }
    )
    return DynamicResult(env_id, frame)


def game_options(meta: dict[str, Any]) -> dict[str, Any]:
    """The rate-limited game a saved adversary records, as :func:`evaluate_dynamic` keywords.

    A run of rrls before the TC-RMDP game recorded ``rate_limit`` alone: its game is
    ``rate_game="target"``, replayed as it was trained.
    """
    if meta.get("rate_limit") is None:
        return {"rate_limit": None, "context": bool(meta.get("context", False))}
    return {
        "rate_limit": float(meta["rate_limit"]),
        "context": bool(meta.get("context", False)),
        "rate_game": meta.get("rate_game") or "target",
        "observe": meta.get("observe") or "vanilla",
        "history": int(meta.get("history") or 1),
        "omniscient": bool(meta.get("omniscient", True)),
    }


def evaluate_run_dynamic(
    run_dir: str | Path, episodes: int = 10, seed: int = 0, batch_size: int = 64
) -> DynamicResult:
    """Paper Table 6 for one training run: its protagonist against its own final adversary.

    ``run_dir`` is a RARL or NR-/PR-MDP run of ``rrls train``: ``policy.npz`` and
    ``adversary.npz``, whose metadata name the task, the game and the set (or alpha) it played,
    and, for a rate-limited adversary (TC-RMDP), ``rate_limit``, ``rate_game``, ``observe``,
    ``history`` and ``omniscient`` (:func:`game_options`), and its ``physics``: it is evaluated
    in the game it was trained in.
    """
    from rrls.evaluation.policies import MLPPolicy

    run_dir = Path(run_dir)
    from rrls.rundir import ADVERSARY, POLICY

    path = run_dir / ADVERSARY
    if not path.exists():
        raise FileNotFoundError(
            f"{run_dir} holds no adversary.npz: only RARL and NR-MDP/PR-MDP runs train one"
        )
    protagonist, adversary = MLPPolicy.load(run_dir / POLICY), MLPPolicy.load(path)
    meta = adversary.metadata
    return evaluate_dynamic(
        protagonist,
        adversary,
        meta["task"],
        game=meta.get("game", "adversarial"),
        uncertainty=meta.get("uncertainty", "3d"),
        episodes=episodes,
        seed=seed,
        alpha=float(meta.get("alpha", 0.1)),
        batch_size=batch_size,
        paper=is_paper(meta.get("physics")),
        **game_options(meta),
    )


def _check_arguments(
    episodes: Any, batch_size: Any, history: Any, seed: Any, alpha: Any, rate_limit: Any
) -> None:
    """The static evaluation's rules, one line naming the argument and what is valid."""
    from rrls.evaluation.protocol import (
        check_counts,
        check_episodes,
        check_rate_limit,
        check_seed,
        check_sizes,
    )
    from rrls.wrappers.tc_rmdp import MAX_HISTORY

    check_counts(episodes=episodes, history=history)
    check_episodes(1, episodes)
    check_sizes(batch_size=batch_size)
    if history > MAX_HISTORY:
        raise ValueError(f"history must be at most {MAX_HISTORY:,}, got {history}")
    check_seed(seed)
    if isinstance(alpha, bool) or not isinstance(alpha, (int, float)) or not 0 <= alpha <= 1:
        raise ValueError(f"alpha must be a number in [0, 1], got {alpha!r}")
    check_rate_limit(rate_limit)


def _actions(out: Any, who: str, n: int) -> np.ndarray:
    """A policy's batch of actions, or a ``PolicyError`` naming which policy misbehaved."""
    from rrls.evaluation.lanes import PolicyError

    actions = np.asarray(out)
    if actions.dtype.kind not in "biuf":
        raise PolicyError(f"the {who} returned {actions.dtype} values; actions must be numbers")
    if actions.ndim != 2 or len(actions) != n:
        raise PolicyError(f"the {who} returned shape {actions.shape} for {n} observations")
    if not np.isfinite(actions).all():
        raise PolicyError(f"the {who} returned non-finite actions (NaN or inf)")
    return actions


__all__ = [
    "dynamic_env_id",
    "DynamicResult",
    "evaluate_dynamic",
    "evaluate_run_dynamic",
    "game_options",
    "make_dynamic_env",
]
