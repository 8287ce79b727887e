"""Dynamic evaluation (paper Table 6): a protagonist against a trained adversary, step by step.

The adversary acts every step (:mod:`rrls.evaluation.games`: the parameter game, the RARL
force game, NR-/PR-MDP's action game). Episodes run on the same engine as the static
evaluation (:mod:`rrls.evaluation.engine`) as two-player lanes: both policies called once per
step on the batch, workers, resume from ``out_dir``, the ``terminated``/``diverged`` columns and
divergence handling of the static evaluation. Episode ``e`` starts from ``reset(seed=seeds[e])``,
so a row equals the one-episode loop ``env.reset(seed=seed)`` then
``env.step((protagonist(obs[None])[0], adversary(obs[None])[0]))`` on ``make_dynamic_env(...)``
(in the TC-RMDP game each player on its part of ``obs``, ``env.views``, the omniscient adversary
also on the protagonist's action), whatever the worker count or batch size.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from rrls.evaluation.defaults import Default, keyword_protocol
from rrls.evaluation.games import Game, TwoPlayers, dynamic_env_id, make_dynamic_env
from rrls.physics import is_paper
from rrls.schema import Schema, boolean, integer, number, string
from rrls.wrappers.tc_rmdp import MAX_HISTORY, OBSERVE, RATE_GAMES

#: the games an adversary plays: the set's parameters (RARL), or the action (NR-/PR-MDP)
GAMES = ("adversarial", "nr", "pr")


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


def evaluate_dynamic(
    protagonist: Any,
    adversary: Any,
    task: str,
    game: str = "adversarial",
    uncertainty: str | Default = Default("3d"),
    episodes: int | Default = Default(10),
    seed: int | Default = Default(0),
    alpha: float = 0.1,
    batch_size: int = 64,
    rate_limit: float | None | Default = Default(None),
    context: bool | Default = Default(False),
    paper: bool | Default = Default(False),
    *,
    rate_game: str | Default = Default("tc"),
    observe: str = "vanilla",
    history: int = 1,
    omniscient: bool = True,
    protocol: Any = None,
    workers: int | None = 1,
    out_dir: str | Path | None = None,
    progress: bool | None = None,
) -> DynamicResult:
    """Mean ± std return of ``protagonist`` while ``adversary`` plays the game every step.

    Both are policies ``obs[B, obs_dim] -> actions``: the adversary's actions live in its own
    space (``[-1, 1]^k`` for the parameter game, the agent's action box for NR/PR-MDP).
    ``rate_limit``, ``rate_game``, ``observe``, ``history`` and ``context``: see
    :func:`make_dynamic_env`. In the TC-RMDP game each player gets its part of the flat
    observation, and an ``omniscient`` adversary (the authors' default) also the protagonist's
    action of the step: ``adversary([ψ01, s, a])``. ``paper=True``: on the paper's physics
    (``env_id`` then ends in ``[paper]``).

    Defaults: the ``"3d"`` set, ``episodes=10`` (the paper's), ``seed=0``, no rate limit
    (``rate_game="tc"`` once one is given), no context, the v5 physics (``paper=False``).

    ``protocol``: a :class:`~rrls.evaluation.Protocol` giving the set, ``dynamic_episodes``, the
    seed, the physics, ``context`` and (for the parameter game) the rate-limited game, as a
    benchmark stores them; the keywords build one for interactive use, and passing any of them
    beside it is an error naming them, whatever the value. ``game``, ``alpha``, ``observe``,
    ``history`` and ``omniscient`` describe the players, not the protocol. ``workers``
    (processes; ``None``: every core) and ``batch_size`` (live episodes per worker) change no
    number; with ``out_dir``, finished chunks are kept there and a re-run with the same
    arguments resumes; ``dynamic.csv`` holds the episodes at the end.
    """
    from rrls.evaluation.protocol import check_sizes

    # a protocol's rate limit is the parameter game's; one given by keyword for another game is
    # refused by name (make_dynamic_env)
    rate_applies = protocol is None or game == "adversarial"
    protocol = keyword_protocol(
        "evaluate_dynamic",
        protocol,
        {
            "uncertainty": uncertainty,
            "episodes": episodes,
            "seed": seed,
            "rate_limit": rate_limit,
            "context": context,
            "paper": paper,
            "rate_game": rate_game,
        },
        {"episodes": "dynamic_episodes"},
        episodes=1,  # the static mesh's: unused here
    )
    _check_arguments(protocol.dynamic_episodes, batch_size, history, alpha)
    if workers == 0:  # 0: in this process, as every rrls command reads it
        workers = 1
    check_sizes(workers=workers)
    played = Game(
        task,
        game,
        protocol.uncertainty,
        float(alpha),
        protocol.rate_limit if rate_applies else None,
        protocol.context,
        protocol.paper,
        rate_game=protocol.rate_game,
        observe=observe,
        history=history,
        omniscient=bool(omniscient),
    )
    try:  # the engine's env cache lives only as long as this evaluation
        return _evaluate(
            protagonist, adversary, played, protocol, batch_size, workers, out_dir, progress
        )
    finally:
        from rrls.evaluation.lanes import clear_env_cache

        clear_env_cache()


def _evaluate(
    protagonist: Any,
    adversary: Any,
    game: Game,
    protocol: Any,
    batch_size: int,
    workers: int | None,
    out_dir: str | Path | None,
    progress: bool | None,
) -> DynamicResult:
    import warnings

    from rrls.evaluation import engine, evaldir
    from rrls.evaluation.chunks import CHUNK
    from rrls.evaluation.lanes import Rollouts, episode_seeds, make_rollout_envs
    from rrls.evaluation.policies import as_policy
    from rrls.evaluation.prepared import PreparedPolicy

    episodes = protocol.dynamic_episodes
    seeds = episode_seeds(protocol.seed, 1, episodes)
    # the first lane's env (the game's checks: a nominal set, context in the TC game) gives the
    # episode length; the spec with it keys the same cached envs
    spec = Rollouts(game.task, "game", (), np.zeros((1, 0)), seeds, 1, game=game)
    env = make_rollout_envs(spec, 1)[0]
    spec = replace(spec, max_episode_steps=_episode_steps(env))
    players = TwoPlayers(
        protagonist if isinstance(protagonist, PreparedPolicy) else as_policy(protagonist),
        as_policy(adversary),
        game,
        env.get_wrapper_attr("views") if game.tc else None,
    )
    lanes = max(1, min(batch_size, episodes))
    if out_dir is None:
        cols = engine.run(spec, players, workers, lanes, progress=progress)
    else:
        config = {
            "dynamic": game.env_id,
            "alpha": game.alpha,
            "episodes": episodes,
            "seed": protocol.seed,
            "chunk": CHUNK,
            **_fingerprints(players, env),
        }
        with evaldir.opened(out_dir, config) as chunk_dir:
            cols = engine.run(spec, players, workers, lanes, chunk_dir=chunk_dir, progress=progress)
            frame = _frame(seeds, cols)
            evaldir.write_dynamic(out_dir, frame)
    if out_dir is None:
        frame = _frame(seeds, cols)
    n_diverged = int(frame["diverged"].sum())
    if n_diverged:
        warnings.warn(
            f"{n_diverged} episode(s) diverged (MuJoCo instability); they are kept with the "
            "return reached before the divergence and flagged in the 'diverged' column",
            stacklevel=4,
        )
    return DynamicResult(game.env_id, frame)


def _frame(seeds: np.ndarray, cols: dict[str, np.ndarray]) -> Any:
    import pandas as pd

    n = seeds.shape[1]
    return pd.DataFrame({"episode": np.arange(n), "seed": seeds[0].astype(np.int64), **cols})


def _episode_steps(env: Any) -> int:
    """The game's episode length: its registered time limit (the task's)."""
    spec = env.spec
    if spec is None or spec.max_episode_steps is None:  # pragma: no cover - every game is made
        raise ValueError("the game's env has no time limit")
    return int(spec.max_episode_steps)


def _fingerprints(players: TwoPlayers, env: Any) -> dict[str, str]:
    """Both players' fingerprints on probes of their input widths (a resume with another
    protagonist or adversary is refused)."""
    from rrls.evaluation.prepared import policy_fingerprint as fingerprint

    width = range(env.observation_space.shape[0])
    p_dim = len(width[players.p0 : players.p1])
    a_dim = len(width[players.a0 : players.a1])
    if players.omniscient:
        a_dim += env.action_space[0].shape[0]
    return {
        "protagonist_fingerprint": fingerprint(players.protagonist, p_dim),
        "adversary_fingerprint": fingerprint(players.adversary, a_dim),
    }


#: what an adversary's metadata may say of the game it plays (any adversary: the keys read by
#: :func:`game_options` and the game's own ``game``/``alpha``); other keys are free
GAME_SCHEMA = Schema(
    {
        "game": string(choices=GAMES),
        "alpha": number(0, 1),
        "rate_limit": number(0, null=True),
        "context": boolean(),
        "rate_game": string(choices=RATE_GAMES, null=True),
        "observe": string(choices=OBSERVE, null=True),
        "history": integer(1, MAX_HISTORY, null=True),
        "omniscient": boolean(),
    },
    open=True,
)
#: an ``rrls train`` run's ``adversary.npz`` metadata: its game, and the task, set and physics
#: it was trained on (what :func:`evaluate_run_dynamic` replays)
ADVERSARY_SCHEMA = Schema(
    {
        **GAME_SCHEMA.fields,
        "task": string(required=True),
        "uncertainty": string(),
        "physics": string(null=True),
    },
    open=True,
)


def check_adversary(meta: Any, where: str, schema: Schema = ADVERSARY_SCHEMA) -> dict[str, Any]:
    """An adversary's metadata checked against ``schema`` (``GAME_SCHEMA`` for an adversary
    from elsewhere, which need not name its task): a missing or ill-typed field is one line
    naming ``where`` (the file), the field and what is valid, never a ``KeyError``."""
    return schema.check({} if meta is None else meta, where, "metadata")


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
    run_dir: str | Path,
    episodes: int = 10,
    seed: int = 0,
    batch_size: int = 64,
    *,
    workers: int | None = 1,
    out_dir: str | Path | None = None,
    progress: bool | None = None,
) -> DynamicResult:
    """Paper Table 6 for one training run: its protagonist against its own final adversary.

    ``run_dir`` is a RARL or NR-/PR-MDP run of ``rrls train``: ``policy.npz`` and
    ``adversary.npz``, whose metadata name the task, the game and the set (or alpha) it played,
    and, for a rate-limited adversary (TC-RMDP), ``rate_limit``, ``rate_game``, ``observe``,
    ``history`` and ``omniscient`` (:func:`game_options`), and its ``physics``: it is evaluated
    in the game it was trained in. ``workers``, ``out_dir``, ``progress``: as
    :func:`evaluate_dynamic`.
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
    meta = check_adversary(adversary.metadata, str(path))
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
        workers=workers,
        out_dir=out_dir,
        progress=progress,
    )


def _check_arguments(episodes: Any, batch_size: Any, history: Any, alpha: Any) -> None:
    """The static evaluation's rules for what the protocol does not check (the episodes'
    total, the batch, the players' history and alpha), one line naming the argument."""
    from rrls.evaluation.protocol import check_counts, check_episodes, check_sizes

    check_counts(history=history)
    check_episodes(1, episodes)
    check_sizes(batch_size=batch_size)
    if history > MAX_HISTORY:
        raise ValueError(f"history must be at most {MAX_HISTORY:,}, got {history}")
    if isinstance(alpha, bool) or not isinstance(alpha, (int, float)) or not 0 <= alpha <= 1:
        raise ValueError(f"alpha must be a number in [0, 1], got {alpha!r}")


__all__ = [
    "ADVERSARY_SCHEMA",
    "GAMES",
    "GAME_SCHEMA",
    "check_adversary",
    "dynamic_env_id",
    "DynamicResult",
    "evaluate_dynamic",
    "evaluate_run_dynamic",
    "game_options",
    "make_dynamic_env",
]
