"""Lockstep lanes: one process rolling out many (parameter point, seed) episodes at once.

Every episode is independent: its env is configured exactly as ``env.set_params(**point);
env.reset(seed=seed)`` and stepped until terminated or ``max_episode_steps``. Lockstep batching
changes only *when* an episode is stepped, never its numbers, provided the policy gives each
row the same action whatever the batch (``rrls.evaluation.policies.BatchInvariant``). The policy
runs once per step on all live lanes; a finished lane takes the next episode.
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Iterator
from contextlib import closing, contextmanager
from dataclasses import dataclass
from typing import Any

import numpy as np

from rrls.deprecation import warn_deprecated

__all__ = [
    "LANES",
    "Finished",
    "PolicyError",
    "Rollouts",
    "clear_env_cache",
    "episode_seeds",
    "make_rollout_envs",
    "run_rows",
]

LANES = 64  # live episodes per worker (one policy block)


class PolicyError(ValueError):
    """The policy returned actions of the wrong shape or non-finite values."""


@dataclass
class Rollouts:
    """The episodes to roll out: ``points[p]`` × ``seeds[p, e]``, for ``task`` with env family
    ``kind`` (what the engine runs; a protocol planned for a task makes one, ``from_plan``)."""

    task: str
    kind: str  # "robust" (parameter sets) or "force" (the RARL force set)
    names: tuple[str, ...]
    points: np.ndarray  # (P, d)
    seeds: np.ndarray  # (P, E) uint32
    max_episode_steps: int = 1000
    stack: Any = None  # an EnvStack (disruptors, schedule, context) around each bare env
    paper: bool = False  # the paper's physics (the original's envs and writes)
    #: a two-player game (``rrls.evaluation.games.Game``): every lane plays it, the policy is a
    #: ``TwoPlayers`` (dynamic evaluation); ``names``/``points`` are then empty
    game: Any = None

    @classmethod
    def from_plan(cls, plan: Any, protocol: Any) -> Rollouts:
        """What the engine rolls out for a planned protocol (``Protocol.plan``): every point ×
        its episodes' seeds."""
        return cls(
            plan.resolved.task,
            plan.resolved.family,
            plan.mesh_box.names,
            plan.points,
            episode_seeds(protocol.seed, len(plan.points), protocol.episodes),
            plan.max_episode_steps,
            None if plan.stack.empty else plan.stack,
            paper=plan.paper,
        )

    @property
    def n_episodes(self) -> int:
        return self.seeds.size

    def row(self, r: int) -> tuple[int, int]:
        """(point, episode) of flat row ``r``; rows are point-major."""
        return divmod(r, self.seeds.shape[1])

    def describe(self, r: int) -> str:
        p, e = self.row(r)
        if self.game is not None:
            return f"episode {e} (seed {int(self.seeds[p, e])})"
        point = {n: float(v) for n, v in zip(self.names, self.points[p])}
        return f"mesh point {p} {point}, episode {e} (seed {int(self.seeds[p, e])})"


def episode_seeds(seed: int, n_points: int, episodes: int) -> np.ndarray:
    """Seed of episode ``e`` at point ``p``: from ``SeedSequence(seed, spawn_key=(p, e))``.

    Each (point, episode) gets its own stream, independent of how many points or workers there are.
    """
    out = np.empty((n_points, episodes), dtype=np.uint32)
    for p in range(n_points):
        for e in range(episodes):
            out[p, e] = np.random.SeedSequence(seed, spawn_key=(p, e)).generate_state(1)[0]
    return out


#: envs per (task, family, stack), reused within one evaluation (building is slower than
#: resetting); ``evaluate`` and ``search_worst_case`` empty it when they return. One cache per
#: thread: an evaluation running in another thread neither shares nor loses its envs.
_LOCAL = threading.local()


def _cache() -> dict[tuple[str, str, Any, bool, Any], list[Any]]:
    if not hasattr(_LOCAL, "envs"):
        _LOCAL.envs = {}
    return _LOCAL.envs


def make_rollout_envs(spec: Rollouts, n: int) -> list[Any]:
    """Bare envs of the spec's family and physics (in the spec's stack of wrappers, if any);
    every lane is reset before use."""
    from rrls.envs import FAMILY_ENVS, paper_class

    envs = _cache().setdefault((spec.task, spec.kind, spec.stack, spec.paper, spec.game), [])
    if spec.game is not None:
        while len(envs) < n:
            envs.append(spec.game.make_env())
        return envs[:n]
    cls = FAMILY_ENVS[spec.kind][spec.task]
    if spec.paper:
        cls = paper_class(cls)
    while len(envs) < n:
        envs.append(cls() if spec.stack is None else spec.stack(cls()))
    return envs[:n]


def clear_env_cache() -> None:
    """Close and forget this thread's cached envs (no state survives from one evaluation to
    the next)."""
    cache = _cache()
    for envs in cache.values():
        for env in envs:
            env.close()
    cache.clear()


Finished = list[tuple[int, float, int, bool, bool]]  # (row, return, length, terminated, diverged)


def run_rows(
    spec: Rollouts,
    policy: Callable[[np.ndarray], Any],
    next_row: Callable[[int], int],
    on_finished: Callable[[Finished], None],
    lanes: int = LANES,
    fast: bool = True,
    on_step: Callable[[int], None] | None = None,
    threads: int = 1,
) -> None:
    """Roll out episodes in lockstep until no lane is live and ``next_row(live)`` returns -1.

    Whenever episodes end, idle lanes ask for rows (``live``: the lanes still running) until one
    is refused, so the batch stays full while rows remain; ``on_finished`` receives the rows
    finished at each step; ``on_step`` the steps within which a lane will surely be free (0 if
    one is already), for work stealing. ``threads``: how many threads step the lanes' physics
    (``rrls.evaluation.kernels.LaneSteps``; the same numbers whatever the count).
    """
    from rrls.evaluation.kernels import make_stepper

    n_lanes = max(1, lanes)
    envs = make_rollout_envs(spec, n_lanes)
    stepper = make_stepper(envs, spec.task, fast=fast, threads=threads)
    space = envs[0].action_space  # a game's: (protagonist's box, adversary's box)
    act_dim = tuple(s.shape[0] for s in space) if spec.game is not None else space.shape[0]
    obs_dim = envs[0].observation_space.shape[0]

    obs = np.zeros((n_lanes, obs_dim))
    lane_row = np.full(n_lanes, -1)  # flat row index of the lane's episode, -1 = idle
    returns = np.zeros(n_lanes)
    lengths = np.zeros(n_lanes, dtype=np.int64)

    def start(lane: int, row: int) -> None:
        lane_row[lane] = row
        p, e = spec.row(row)
        env = envs[lane]
        if spec.game is None:  # a game's adversary sets the parameters itself
            env.reset_params()
        if spec.names:
            env.set_params(**dict(zip(spec.names, spec.points[p].tolist())))
        obs[lane], _ = env.reset(seed=int(spec.seeds[p, e]))
        returns[lane] = 0.0
        lengths[lane] = 0
        stepper.reset(lane, obs[lane])

    def fill() -> None:
        """Give idle lanes new rows while ``next_row`` hands some out."""
        for lane in np.flatnonzero(lane_row < 0).tolist():
            row = next_row(int(np.count_nonzero(lane_row >= 0)))
            if row < 0:
                return
            start(lane, row)

    with _quiet_mujoco(), closing(stepper):
        fill()
        _loop(
            spec,
            policy,
            stepper,
            fill,
            on_finished,
            on_step,
            obs,
            lane_row,
            returns,
            lengths,
            act_dim,
        )


@contextmanager
def _quiet_mujoco() -> Iterator[None]:
    """Keep MuJoCo's instability messages out of stderr and ``MUJOCO_LOG.TXT``.

    Unstable episodes are flagged per row (``diverged``) and summarised once by ``evaluate``.
    """
    import mujoco

    previous = mujoco.get_mju_user_warning()
    mujoco.set_mju_user_warning(lambda msg: None)
    try:
        yield
    finally:
        mujoco.set_mju_user_warning(previous)


def _loop(
    spec: Rollouts,
    policy: Callable[[np.ndarray], Any],
    stepper: Any,
    fill: Callable[[], None],
    on_finished: Callable[[Finished], None],
    on_step: Callable[[int], None] | None,
    obs: np.ndarray,
    lane_row: np.ndarray,
    returns: np.ndarray,
    lengths: np.ndarray,
    act_dim: Any,
) -> None:
    while (lane_row >= 0).any():
        live = np.flatnonzero(lane_row >= 0)
        if spec.game is None:
            actions = np.asarray(policy(obs[live]))
            _check_actions(actions, live, lane_row, lengths, spec, act_dim)
        else:  # two players: the protagonist, then the adversary (which may see its actions)
            agent = np.asarray(policy.protagonist_actions(obs[live]))
            _check_actions(agent, live, lane_row, lengths, spec, act_dim[0], "the protagonist")
            adv = np.asarray(policy.adversary_actions(obs[live], agent))
            _check_actions(adv, live, lane_row, lengths, spec, act_dim[1], "the adversary")
            actions = _Joint(agent, adv)
        new_obs, rewards, terminated, diverged = stepper.step(live, actions)
        obs[live] = new_obs
        # a diverged step is not counted: the row keeps the return and length reached before it
        returns[live] += np.where(diverged, 0.0, rewards)
        lengths[live] += ~diverged
        done = np.flatnonzero(terminated | diverged | (lengths[live] >= spec.max_episode_steps))
        if len(done):
            finished = [
                (
                    int(lane_row[live[j]]),
                    float(returns[live[j]]),
                    int(lengths[live[j]]),
                    bool(terminated[j]),
                    bool(diverged[j]),
                )
                for j in done
            ]
            on_finished(finished)
            lane_row[live[done]] = -1
            fill()
        if on_step is not None:
            busy = lane_row >= 0
            on_step(int(spec.max_episode_steps - lengths.max()) if busy.all() else 0)


class _Joint:
    """Both players' actions of one step, row ``j`` as the pair a game's ``env.step`` takes
    (each player's array keeps its own dtype)."""

    def __init__(self, agent: np.ndarray, adversary: np.ndarray) -> None:
        self.agent, self.adversary = agent, adversary

    def __getitem__(self, j: int) -> tuple[np.ndarray, np.ndarray]:
        return self.agent[j], self.adversary[j]


def _check_actions(
    actions: np.ndarray,
    live: np.ndarray,
    lane_row: np.ndarray,
    lengths: np.ndarray,
    spec: Rollouts,
    act_dim: int,
    who: str = "policy",
) -> None:
    if actions.dtype.kind not in "biuf":
        r = int(lane_row[live[0]])
        raise PolicyError(
            f"{who} returned {actions.dtype} values; actions must be real numbers — at "
            f"{spec.describe(r)}, step {lengths[live[0]]}"
        )
    if actions.shape != (len(live), act_dim):
        r = int(lane_row[live[0]])
        raise PolicyError(
            f"{who} returned actions of shape {actions.shape} for {len(live)} observations; "
            f"expected ({len(live)}, {act_dim}) — at {spec.describe(r)}, step {lengths[live[0]]}"
        )
    bad = ~np.isfinite(actions).all(axis=1)
    if bad.any():
        j = int(np.flatnonzero(bad)[0])
        r = int(lane_row[live[j]])
        raise PolicyError(
            f"{who} returned non-finite actions {actions[j].tolist()} at {spec.describe(r)}, "
            f"step {lengths[live[j]]}"
        )


def __getattr__(name: str) -> Any:
    """``RolloutSpec``: :class:`Rollouts`'s former name (deprecated: it is no specification, and
    was one of several unrelated ``*Spec`` classes of rrls)."""
    if name == "RolloutSpec":
        warn_deprecated(
            "rrls.evaluation.lanes.RolloutSpec is deprecated; use rrls.evaluation.lanes.Rollouts "
            "(the same class)"
        )
        return Rollouts
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
