"""Work sharing between evaluation workers: equal contiguous shares of the rows, then stealing
single rows from the largest share whose owner cannot start them soon. Which worker runs a row
changes only who runs it, never its numbers."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from rrls.evaluation.lanes import LANES

__all__ = ["WorkPlan", "plan_work", "shared_bounds", "steal_horizon", "take_row"]


@dataclass(frozen=True)
class WorkPlan:
    """How ``n`` rows are split among workers: ``shares[w]`` = (start, stop) offsets, and lanes.

    Why: the unit of saving (a ``CHUNK``) must not be the unit of work (512 rows = 11 chunks
    would keep 5 of 16 workers idle), and one shared counter hands the last wave to whoever asks
    first. Equal shares start every worker with the same load; stealing (:func:`take_row`) evens
    out episodes of different lengths.
    """

    shares: tuple[tuple[int, int], ...]
    lanes: int

    @property
    def workers(self) -> int:
        return len(self.shares)


def plan_work(n: int, workers: int, lanes: int = LANES) -> WorkPlan:
    """Split ``n`` rows into ``min(workers, n)`` contiguous shares whose sizes differ by <= 1.

    Each worker runs ``min(lanes, largest share)`` lanes: no lane is built that would never get an
    episode. The split changes only who runs a row, never its numbers.
    """
    if workers < 1:
        raise ValueError(f"workers must be >= 1, got {workers}")
    workers = max(1, min(workers, n))
    base, extra = divmod(n, workers)
    shares, start = [], 0
    for w in range(workers):
        stop = start + base + (w < extra)
        shares.append((start, stop))
        start = stop
    return WorkPlan(tuple(shares), max(1, min(lanes, -(-n // workers))))


def take_row(bounds: Any, w: int, live: int = 0, horizon: int = 0) -> int:
    """Next row offset for worker ``w`` (running ``live`` lanes), or -1: none for it now.

    ``bounds`` is ``[next_0, stop_0, soon_0, next_1, ...]`` (a shared array, under its lock):
    worker ``v``'s unstarted rows are ``next_v:stop_v``, and within ``soon_v`` steps one of its
    lanes will surely be free (all its lanes are busy while it has rows; an episode ends at
    ``max_episode_steps`` at the latest). A worker takes the front of its own share, then steals
    the last row of the largest share whose owner cannot start it within ``horizon`` steps.
    Why not steal greedily: with equal episode lengths all workers reach the last wave together,
    and whoever asks first would take a full set of lanes from the others' shares (5000 rows on
    16 x 64 lanes: 14 workers with 64, one with 8, one with none), which makes those workers'
    steps slower. A worker with no live lane takes any row left, so none idles while rows remain.
    """
    if bounds[3 * w] < bounds[3 * w + 1]:
        i = bounds[3 * w]
        bounds[3 * w] = i + 1
        return int(i)
    victim, most = -1, 0
    for v in range(len(bounds) // 3):
        left = bounds[3 * v + 1] - bounds[3 * v]
        if left > most and (live == 0 or bounds[3 * v + 2] > horizon):
            victim, most = v, left
    if victim < 0:
        return -1
    bounds[3 * victim + 1] -= 1
    return int(bounds[3 * victim + 1])


def shared_bounds(plan: WorkPlan, max_episode_steps: int) -> list[int]:
    """The initial ``bounds`` of :func:`take_row`: each share, and "not started" as far away."""
    return [i for a, b in plan.shares for i in (a, b, max_episode_steps)]


def steal_horizon(max_episode_steps: int) -> int:
    """Rows whose owner frees a lane within 5 % of an episode are left to it (see take_row)."""
    return max(1, max_episode_steps // 20)
