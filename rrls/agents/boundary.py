"""Ctrl-C at a training step's end: ``StepBoundary`` holds it (and SIGTERM where it stands for
Ctrl-C, in a benchmark's run process) until the step it came in ends, so that the loop writes a
checkpoint of a consistent state and stops; ``rrls train`` and the benchmark's runs stop this way.
"""

from __future__ import annotations

import signal
import threading
from typing import Any

from rrls.interrupts import terms_as_ctrl_c


class StepBoundary:
    """Ctrl-C held until the training step it came in ends (``requested``), so that the loop
    writes a checkpoint of a consistent state (no update, episode or buffer left half-way) and
    then stops; a second Ctrl-C stops at once. Only where Ctrl-C is Python's default (the main
    thread); in a benchmark's run process, which ignores Ctrl-C, the driver's SIGTERM is held
    the same way (``rrls.interrupts.term_as_ctrl_c``)."""

    def __init__(self) -> None:
        self.requested = False
        self._previous: dict[int, Any] = {}

    def hold(self) -> None:
        """From now on Ctrl-C (and SIGTERM where it is Ctrl-C) only sets ``requested`` (until
        ``release``)."""
        held = ctrl_c_signals()
        for sig in held:
            self._previous[sig] = signal.signal(sig, self._request)
        if held:
            self.requested = False

    def _request(self, signum: int, frame: Any) -> None:
        # a second Ctrl-C stops at once; a second SIGTERM does not (a scheduler signals every
        # process of a job, and a benchmark's driver then stops its runs with one more)
        if self.requested and signum == signal.SIGINT:
            raise KeyboardInterrupt
        self.requested = True

    def release(self) -> None:
        """Ctrl-C (and SIGTERM) as before ``hold``."""
        for sig, previous in self._previous.items():
            signal.signal(sig, previous)
        self._previous = {}

    def __enter__(self) -> StepBoundary:
        self.hold()
        return self

    def __exit__(self, *exc: object) -> None:
        self.release()


def active_ctrl_c() -> bool:
    """Whether Ctrl-C raises ``KeyboardInterrupt`` here (Python's default handler, main thread)."""
    return (
        threading.current_thread() is threading.main_thread()
        and signal.getsignal(signal.SIGINT) is signal.default_int_handler
    )


def ctrl_c_signals() -> list[int]:
    """The signals that are Ctrl-C here: SIGINT where :func:`active_ctrl_c`, and SIGTERM in
    the main thread where it was made Ctrl-C (``rrls.interrupts.term_as_ctrl_c``)."""
    held = [signal.SIGINT] if active_ctrl_c() else []
    if threading.current_thread() is threading.main_thread() and terms_as_ctrl_c():
        held.append(signal.SIGTERM)
    return held
