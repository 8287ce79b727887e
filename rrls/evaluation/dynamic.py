"""Dynamic evaluation (paper Table 6): a protagonist against a trained adversary, step by step.

The adversary acts every step — choosing the physical parameters (``DynamicAdversarial``, over a
parameter set or the RARL force set) or perturbing the action (``ProbabilisticActionRobust``,
NR-MDP/PR-MDP). Episodes run in lockstep (both policies called once per step on the batch);
each episode ``e`` starts from ``reset(seed=seeds[e])``, so a row equals the one-episode loop
``env.reset(seed=seed)`` then ``env.step((protagonist(obs[None])[0], adversary(obs[None])[0]))``
on ``make_dynamic_env(...)``.
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
) -> Any:
    """The two-player env: the registered id, or ``ProbabilisticActionRobust`` with ``alpha``.

    For the parameter game, ``rate_limit=L`` is TC-RMDP's rate-limited adversary (the parameters
    move at most ``L`` per step in the set's normalised units) and ``context=True`` appends the
    parameters in force, normalised to the set, to the shared observation (TC-RMDP's oracle);
    ``uncertainty`` may then also be an ``UncertaintySet``. This is the env both training (RARL
    ``--rate-limit``) and :func:`evaluate_dynamic` play. ``paper=True``: on the paper's physics.

    >>> env = make_dynamic_env("hopper", uncertainty="2d", rate_limit=0.05, context=True)
    >>> env.observation_space.shape, env.get_wrapper_attr("rate_limit")
    ((13,), 0.05)
    """
    import gymnasium as gym

    kw = {"paper": True} if paper else {}
    if game != "adversarial" and (rate_limit is not None or context):
        raise ValueError("rate_limit and context apply to the parameter game (game='adversarial')")
    if game == "adversarial" and (
        rate_limit is not None or context or not isinstance(uncertainty, str)
    ):
        from rrls.envs import resolve
        from rrls.wrappers import ContextObservation, DynamicAdversarial

        resolved = resolve(task, uncertainty)
        if resolved.is_nominal:
            raise ValueError("the nominal model has no parameters for an adversary to play")
        base = gym.make(f"rrls/{resolved.family}-{resolved.task}-v0", **kw)
        env = DynamicAdversarial(base, resolved.box, rate_limit=rate_limit)
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
) -> DynamicResult:
    """Mean ± std return of ``protagonist`` while ``adversary`` plays the game every step.

    Both are policies ``obs[B, obs_dim] -> actions``: the adversary's actions live in its own
    space (``[-1, 1]^k`` for the parameter game, the agent's action box for NR/PR-MDP).
    ``rate_limit`` and ``context``: see :func:`make_dynamic_env` (TC-RMDP's game and oracle);
    ``paper=True``: on the paper's physics (``env_id`` then ends in ``[paper-v4]``).
    """
    import pandas as pd

    from rrls.evaluation.policies import as_policy
    from rrls.evaluation.runner import episode_seeds

    if episodes < 1:
        raise ValueError(f"episodes must be >= 1, got {episodes}")
    extras = {"rate_limit": rate_limit, "context": context}
    if rate_limit is None and not context and isinstance(uncertainty, str):
        env_id = dynamic_env_id(task, game, uncertainty)
    else:
        env_id = f"{task}-adversarial ({uncertainty}, rate_limit={rate_limit}, context={context})"
    if paper:
        env_id += f" [{PAPER}]"
    extras["paper"] = paper
    protagonist, adversary = as_policy(protagonist), as_policy(adversary)
    seeds = episode_seeds(seed, 1, episodes)[0]
    n_lanes = max(1, min(batch_size, episodes))
    envs = [make_dynamic_env(task, game, uncertainty, alpha, **extras) for _ in range(n_lanes)]
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
        agent = _actions(protagonist(batch), "protagonist", len(live))
        adv = _actions(adversary(batch), "adversary", len(live))
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


def evaluate_run_dynamic(
    run_dir: str | Path, episodes: int = 10, seed: int = 0, batch_size: int = 64
) -> DynamicResult:
    """Paper Table 6 for one training run: its protagonist against its own final adversary.

    ``run_dir`` is a RARL or NR-/PR-MDP run of ``rrls train``: ``policy.npz`` and
    ``adversary.npz``, whose metadata name the task, the game and the set (or alpha) it played,
    and, for a rate-limited adversary (TC-RMDP), ``rate_limit`` (and ``context`` if the policies
    observed the parameters), and its ``physics``: it is evaluated in the game it was trained in.
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
        rate_limit=None if meta.get("rate_limit") is None else float(meta["rate_limit"]),
        context=bool(meta.get("context", False)),
        paper=is_paper(meta.get("physics")),
    )


def _actions(out: Any, who: str, n: int) -> np.ndarray:
    """A policy's batch of actions, or a ``PolicyError`` naming which policy misbehaved."""
    from rrls.evaluation.runner import PolicyError

    actions = np.asarray(out)
    if actions.dtype.kind not in "biuf":
        raise PolicyError(f"the {who} returned {actions.dtype} values; actions must be numbers")
    if actions.ndim != 2 or len(actions) != n:
        raise PolicyError(f"the {who} returned shape {actions.shape} for {n} observations")
    return actions
