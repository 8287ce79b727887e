"""What a command says when Ctrl-C stops it: one line with what was kept on disk, read from the
disk when the interrupt comes, and the exact command that goes on from there (``rrls.cli.main``
prints it and exits 130).

The code that knows what it writes (a command, the benchmark's driver) turns Ctrl-C into an
:class:`Interruption` carrying that, with :func:`keeping`:

>>> try:
...     with keeping(lambda: "3 of 10 chunks kept in ev"):
...         raise KeyboardInterrupt
... except KeyboardInterrupt as stop:
...     print(interrupted("evaluate", ["evaluate", "p.npz", "--out", "ev"], stop.kept))
rrls evaluate: interrupted; 3 of 10 chunks kept in ev; to go on: rrls evaluate p.npz --out ev
"""

from __future__ import annotations

import shlex
import signal
import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path

__all__ = [
    "NOTHING_YET",
    "Interruption",
    "identity",
    "interrupted",
    "keeping",
    "sigterm_as_ctrl_c",
    "term_as_ctrl_c",
    "terms_as_ctrl_c",
]

#: what is kept when Ctrl-C comes before a command wrote anything
NOTHING_YET = "nothing written yet"


class Interruption(KeyboardInterrupt):
    """Ctrl-C, with what was kept (``kept``, one phrase) and whether the same command goes on
    from it (``resumes``: True; False: it starts again; None: nothing is left to do). Still a
    ``KeyboardInterrupt``: whatever stops on Ctrl-C stops on it."""

    def __init__(self, kept: str, resumes: bool | None = True) -> None:
        super().__init__(kept)
        self.kept, self.resumes = kept, resumes


@contextmanager
def keeping(describe: Callable[[], str | tuple[str, bool | None]]) -> Iterator[None]:
    """Turn Ctrl-C inside the block into an :class:`Interruption` saying what ``describe()``
    finds kept then (a phrase, or ``(phrase, resumes)``); an inner one passes unchanged."""
    try:
        yield
    except Interruption:
        raise
    except KeyboardInterrupt:
        said = describe()
        kept, resumes = said if isinstance(said, tuple) else (said, True)
        raise Interruption(kept, resumes) from None


def term_as_ctrl_c() -> None:
    """From now on SIGTERM is Ctrl-C in this process (``KeyboardInterrupt``). For a process
    that a driver stops with SIGTERM (a benchmark's run process, which ignores Ctrl-C itself):
    its training loop then finishes the step it is in and writes a checkpoint of it before
    stopping, as ``rrls train`` does on Ctrl-C (``rrls.agents.boundary.StepBoundary``)."""
    signal.signal(signal.SIGTERM, _ctrl_c)


@contextmanager
def sigterm_as_ctrl_c() -> Iterator[None]:
    """SIGTERM is Ctrl-C inside the block (in the main thread; elsewhere nothing changes): the
    polite stop of a scheduler (SLURM at its time limit, a preempted node, ``kill``) keeps what
    Ctrl-C keeps, a checkpoint of the step a run is in, and says how to go on."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.signal(signal.SIGTERM, _ctrl_c)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


def terms_as_ctrl_c() -> bool:
    """Whether SIGTERM is Ctrl-C here (:func:`term_as_ctrl_c`)."""
    return signal.getsignal(signal.SIGTERM) is _ctrl_c


def _ctrl_c(signum: int, frame: object) -> None:
    raise KeyboardInterrupt


def identity(path: str | Path) -> tuple[int, int] | None:
    """A file or folder's inode, None when absent: whether a command replaced it by the time
    of the interrupt (a file written atomically, a folder rebuilt beside: a new inode)."""
    try:
        stat = Path(path).stat()
    except OSError:
        return None
    return stat.st_dev, stat.st_ino


def interrupted(command: str, argv: list[str], kept: str, resumes: bool | None = True) -> str:
    """The one line ``rrls COMMAND`` prints on Ctrl-C: what was kept, and the exact command
    that goes on from there (``train`` adds ``--resume``, drops ``--overwrite``), or the one
    that starts again when nothing is kept to go on from (none when nothing is left to do)."""
    line = f"rrls {command}: interrupted; {kept}"
    if resumes is None:
        return line
    again = ["rrls", *argv]
    if command == "train" and resumes:  # --overwrite would start over: the same run, resumed
        again = [a for a in again if a != "--overwrite"]
        if "--resume" not in again:
            again.append("--resume")
    return f"{line}; {'to go on' if resumes else 'to start again'}: {shlex.join(again)}"
