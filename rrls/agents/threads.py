"""How many threads a training run uses: all idle cores when alone, one when the machine is shared.

OpenMP threads spin at every barrier, so a run that uses two threads while another process
wants a core does not slow down by half but by 3-30x (measured on 2 cores: two runs with two
threads each took 118 s for what took 38 s with one thread each). ``AdaptiveThreads`` watches how
much CPU *other* processes use (``/proc/stat`` minus this process's own time) and keeps
``torch``'s intra-op threads at the number of cores they leave idle, re-checked every couple of
seconds. Two runs side by side each see the other's load and settle at one thread; a run left
alone goes back to all cores. Without ``/proc`` (macOS, Windows) it stays at one thread.
"""

from __future__ import annotations

import os
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import torch

from rrls._proc import cores


def _busy_jiffies() -> tuple[int, int] | None:
    """(busy, total) CPU jiffies of the whole machine, or None without ``/proc``."""
    try:
        fields = Path("/proc/stat").read_text().split("\n", 1)[0].split()[1:]
    except OSError:
        return None
    values = [int(v) for v in fields]
    idle = values[3] + (values[4] if len(values) > 4 else 0)  # idle + iowait
    return sum(values[:8]) - idle, sum(values[:8])


def _own_jiffies() -> int:
    """This process's CPU time (all threads), in jiffies."""
    t = os.times()
    return round((t.user + t.system) * os.sysconf("SC_CLK_TCK"))


class AdaptiveThreads:
    """Sets torch's thread count to the cores other processes leave idle (``fixed``: that many).

    ``poll()`` is cheap (a clock read) and re-measures every ``interval`` seconds.
    """

    def __init__(self, fixed: int | None = None, interval: float = 2.0) -> None:
        import torch

        self._torch = torch
        self.previous = torch.get_num_threads()
        self.cores = cores()
        self.fixed = fixed
        self.interval = interval
        self._last = _busy_jiffies()
        self._own = _own_jiffies()
        self._time = time.monotonic()
        if fixed is not None:
            self.threads = max(1, int(fixed))
        elif self._last is None:
            self.threads = 1
        else:  # a first short look: is anyone else busy right now?
            time.sleep(0.2)
            self.threads = self._measure()
        torch.set_num_threads(self.threads)

    def _measure(self) -> int:
        now, own = _busy_jiffies(), _own_jiffies()
        if now is None or self._last is None:
            return self.threads
        busy, total = now[0] - self._last[0], now[1] - self._last[1]
        others = max(0, busy - (own - self._own))
        self._last, self._own, self._time = now, own, time.monotonic()
        if total <= 0:
            return getattr(self, "threads", 1)
        others_cores = others / total * self.cores
        # cores left idle by everyone else, rounded down with a little slack for daemons
        return max(1, min(self.cores, int(self.cores - others_cores + 0.25)))

    def poll(self) -> int:
        """Re-measure if due and adjust torch's threads; returns the current count."""
        if self.fixed is None and time.monotonic() - self._time >= self.interval:
            threads = self._measure()
            if threads != self.threads:
                self.threads = threads
                self._torch.set_num_threads(threads)
        return self.threads

    def restore(self) -> None:
        """Give the process back the thread count it had before."""
        self._torch.set_num_threads(self.previous)


@contextmanager
def process_settings(threads: int | None) -> Iterator[Any]:
    """The process as training wants it, put back as it was afterwards.

    Threads: torch's intra-op threads follow ``AdaptiveThreads`` (the cores other processes
    leave idle, or ``threads``); numpy's BLAS is held to one thread (``threadpoolctl``): acting
    is batch-1 products whose extra BLAS threads only spin, and measured, they cost a default
    Hopper run ~20 % (``OMP_NUM_THREADS=1`` made it that much faster). Denormals are flushed to
    zero: dead ReLU units' Adam moments decay through the denormal range, where x86 arithmetic
    is ~100x slower (measured: each Adam step 5x slower).
    """
    from threadpoolctl import threadpool_limits

    flushed = flush_denormal_enabled()
    torch.set_flush_denormal(True)
    adaptive = AdaptiveThreads(threads)
    try:
        with threadpool_limits(1, user_api="blas"):
            yield adaptive
    finally:
        adaptive.restore()
        torch.set_flush_denormal(flushed)


def flush_denormal_enabled() -> bool:
    """Whether this thread flushes float32 denormals to zero (torch has no getter for it)."""
    tiny = torch.tensor([1e-37], dtype=torch.float32)
    return bool((tiny * 1e-3).item() == 0.0)
