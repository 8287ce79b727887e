"""Process utilities, once, below every layer that uses them: cores, die-with-parent, a
directory lock, one-thread BLAS/OpenMP settings, children started with Ctrl-C held."""

from __future__ import annotations

import os
import signal
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager

#: environment of a process that must use one BLAS/OpenMP thread (set before numpy loads)
THREAD_ENV = {
    "OMP_NUM_THREADS": "1",
    "MKL_NUM_THREADS": "1",
    "OPENBLAS_NUM_THREADS": "1",
    "NUMEXPR_NUM_THREADS": "1",
}


def cores() -> int:
    """The cores this process may run on (its affinity on Linux, else the machine's)."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not Linux
        return os.cpu_count() or 1


def die_with_parent(parent: int | None = None) -> None:
    """Make this process die with its parent, even after ``kill -9``: no orphan keeps working
    (or stays blocked on a queue). ``parent``: the pid the parent had when it started this
    process (default: the current parent), so a parent that died before this call is seen.

    Linux: ``prctl(PR_SET_PDEATHSIG, SIGKILL)``; elsewhere (or if that fails) a daemon thread
    that polls the parent pid.
    """
    parent = os.getppid() if parent is None else parent
    if sys.platform.startswith("linux"):
        try:
            import ctypes
            import signal

            libc = ctypes.CDLL(None, use_errno=True)
            if libc.prctl(1, int(signal.SIGKILL), 0, 0, 0) == 0:  # PR_SET_PDEATHSIG
                if os.getppid() != parent:  # the parent died before prctl took effect
                    os._exit(1)
                return
        except (OSError, AttributeError):  # pragma: no cover - no libc/prctl: poll instead
            pass
    import threading

    def watch() -> None:  # pragma: no cover - non-Linux fallback
        while os.getppid() == parent:
            time.sleep(1.0)
        os._exit(1)

    threading.Thread(target=watch, name="rrls-parent-watch", daemon=True).start()
    if os.getppid() != parent:
        os._exit(1)


@contextmanager
def single_thread_env() -> Iterator[None]:
    """Children spawned inside inherit one-thread BLAS/OpenMP settings (restored after)."""
    saved = {k: os.environ.get(k) for k in THREAD_ENV}
    os.environ.update(THREAD_ENV)
    try:
        yield
    finally:
        for k, v in saved.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


#: the signals that stop a command: Ctrl-C, and a scheduler's SIGTERM (``rrls.interrupts``)
STOP_SIGNALS = frozenset({signal.SIGINT, signal.SIGTERM})


@contextmanager
def stops_held() -> Iterator[None]:
    """Hold Ctrl-C and SIGTERM while child processes are started. One landing in the instant a
    child is forked (its at-fork handlers) or spawned (its interpreter still importing) raises
    there, before the child's own handlers are set, and prints a traceback. Held, it reaches
    this process once the children are started, and each child once it calls
    :func:`release_stops` (a child inherits the held mask, across ``exec`` too)."""
    if not hasattr(signal, "pthread_sigmask"):  # pragma: no cover - not POSIX
        yield
        return
    before = signal.pthread_sigmask(signal.SIG_BLOCK, STOP_SIGNALS)
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, before)


def release_stops() -> None:
    """In a child started under :func:`stops_held`, once its own handlers are set: the stop
    signals held since it started arrive now."""
    if hasattr(signal, "pthread_sigmask"):
        signal.pthread_sigmask(signal.SIG_UNBLOCK, STOP_SIGNALS)
