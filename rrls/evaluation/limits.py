"""The limits an evaluation's numbers must keep, each a one-line refusal naming the value:
counts, episodes, workers and batch sizes, seeds, the TC-RMDP rate limit. Apart from
``protocol.py`` (which re-exports them) so that the protocol reads as the protocol."""

from __future__ import annotations

from typing import Any

import numpy as np

__all__ = [
    "MAX_EPISODES",
    "MAX_LANES",
    "MAX_WORKERS",
    "check_counts",
    "check_episodes",
    "check_rate_limit",
    "check_seed",
    "check_sizes",
]

#: the most episodes one evaluation plans (10**8 episodes of 1 000 steps: 10**11 env steps)
MAX_EPISODES = 100_000_000


def check_counts(**values: Any) -> None:
    """Refuse counts below 1 (and non-integers), naming the argument."""
    for name, value in values.items():
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
            raise ValueError(f"{name} must be an integer >= 1, got {value!r}")


def check_episodes(points: int, episodes: int) -> None:
    """Refuse an evaluation of more than ``MAX_EPISODES`` episodes (one line with the sum)."""
    if points * episodes > MAX_EPISODES:
        raise ValueError(
            f"{points:,} points x {episodes:,} episodes = {points * episodes:,} episodes; at "
            f"most {MAX_EPISODES:,} per evaluation"
        )


#: worker processes and live episodes per worker an evaluation may ask for (results depend on
#: neither: more than this only costs processes and memory)
MAX_WORKERS = 1024
MAX_LANES = 1_000_000


def check_sizes(workers: Any = None, batch_size: Any = None) -> None:
    """Refuse worker counts and batch sizes below 1 or above their limits, naming them."""
    for name, value, most in (
        ("workers", workers, MAX_WORKERS),
        ("batch_size", batch_size, MAX_LANES),
    ):
        if value is None:
            continue
        check_counts(**{name: value})
        if value > most:
            raise ValueError(f"{name} must be at most {most:,}, got {value}")


def check_seed(seed: Any) -> None:
    """Refuse a seed that is not an integer in ``[0, 2**32)``."""
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or not 0 <= seed < 2**32:
        raise ValueError(f"seed must be an integer in [0, 2**32), got {seed!r}")


def check_rate_limit(rate: Any) -> None:
    """Refuse a TC-RMDP rate limit that is neither None nor a finite number > 0."""
    if rate is not None and (
        isinstance(rate, bool)
        or not isinstance(rate, (int, float, np.floating))
        or not np.isfinite(rate)
        or rate <= 0
    ):
        raise ValueError(f"rate_limit must be None (null) or a finite number > 0, got {rate!r}")
