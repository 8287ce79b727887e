"""The progress every long command shows (training, evaluations), the same way everywhere: a
tqdm bar on a terminal, plain lines where stderr is not one (a log file, a pipe, CI).

Why not tqdm alone: under a pseudo-terminal that reports no size (0 x 0: ``script``, a
container started with ``-t``, some CI runners and IDE consoles) tqdm computes -1 rows and
hides every bar; in a log it writes carriage-return updates that pile up on one line.
"""

from __future__ import annotations

import os
import re
import sys
import time
from collections.abc import Callable
from typing import Any, TextIO

__all__ = [
    "EVERY_PERCENT",
    "EVERY_SECONDS",
    "PLAIN_LINE",
    "PlainProgress",
    "progress_bar",
    "terminal_shape",
]

#: plain lines: one each time this share of the total is done ...
EVERY_PERCENT = 10
#: ... or this long after the last line, whichever comes first
EVERY_SECONDS = 60.0
#: a plain line: ``DESC: P% (N of T UNITs), M:SS elapsed[, M:SS left][, postfix]`` (what a
#: reader of a log, or a test, tells apart from the command's own lines)
PLAIN_LINE = re.compile(r"^.+?: +\d+% \([\d,]+ of [\d,]+ \w+\), [\d:]+ elapsed(, .+)?$")


def progress_bar(
    total: int,
    *,
    unit: str,
    desc: str,
    shown: bool | None = None,
    initial: int = 0,
    smoothing: float = 0.1,
    stream: TextIO | None = None,
) -> Any:
    """A progress display with tqdm's ``update``/``set_postfix``/``close``. ``shown``: None (a
    library's default) a bar on a terminal and nothing elsewhere; True (the commands') a bar on
    a terminal and plain lines elsewhere; False nothing."""
    from tqdm.auto import tqdm

    stream = sys.stderr if stream is None else stream
    terminal = _isatty(stream)
    if shown is False or (shown is None and not terminal):
        return tqdm(total=total, disable=True)
    if not terminal:
        return PlainProgress(total, unit=unit, desc=desc, initial=initial, stream=stream)
    return tqdm(
        total=total,
        initial=initial,
        unit=unit,
        desc=desc,
        smoothing=smoothing,
        file=stream,
        **terminal_shape(stream),
    )


def _isatty(stream: Any) -> bool:
    try:
        return bool(stream.isatty())
    except (AttributeError, ValueError, OSError):  # no such method, or a closed stream
        return False


def terminal_shape(stream: Any) -> dict[str, int]:
    """tqdm's ``ncols``/``nrows`` where the terminal reports no size (it then hides the bar):
    ``$COLUMNS``/``$LINES``, else 80 x 24; nothing where the size is known (tqdm reads it)."""
    try:
        columns, lines = os.get_terminal_size(stream.fileno())
    except (AttributeError, ValueError, OSError):
        columns = lines = 0
    if columns > 0 and lines > 0:
        return {}
    return {"ncols": _env_int("COLUMNS", 80) - 1, "nrows": _env_int("LINES", 24) - 1}


def _env_int(name: str, default: int) -> int:
    try:
        value = int(os.environ.get(name, ""))
    except ValueError:
        return default
    return value if value > 1 else default


class PlainProgress:
    """Progress as whole lines, for logs: ``DESC: 40% (400 of 1,000 episodes), 0:12 elapsed,
    0:18 left``, at the start, at every ``EVERY_PERCENT`` % done or ``EVERY_SECONDS`` after
    the last line, whichever comes first, and at the end."""

    def __init__(
        self,
        total: int,
        *,
        unit: str,
        desc: str,
        initial: int = 0,
        stream: TextIO | None = None,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.total, self.unit, self.desc = max(int(total), 0), unit, desc
        self.n = self.start = int(initial)
        self.stream = sys.stderr if stream is None else stream
        self.clock = clock
        self.postfix: dict[str, Any] = {}
        self.t0 = self.last = clock()
        self.closed = False
        self._mark = self._percent_mark()
        self._shown = -1
        self._line()

    def _percent_mark(self) -> int:
        if self.total <= 0:
            return 0
        return int(100 * self.n / self.total) // EVERY_PERCENT

    def update(self, n: int = 1) -> None:
        self.n += int(n)
        mark = self._percent_mark()
        if mark > self._mark or self.clock() - self.last >= EVERY_SECONDS:
            self._mark = mark
            self._line()

    def set_postfix(self, refresh: bool = True, **values: Any) -> None:
        """Shown at the end of the next line (as tqdm's postfix)."""
        self.postfix = dict(values)

    def close(self) -> None:
        """The last line, where it stopped (unless the last line already said so)."""
        if not self.closed and self._shown != self.n:
            self._line()
        self.closed = True

    def _line(self) -> None:
        now = self.clock()
        self.last, self._shown = now, self.n
        unit = self.unit if self.unit.endswith("s") else f"{self.unit}s"
        share = f"{100 * self.n / self.total:3.0f}% " if self.total else ""
        parts = [
            f"{share}({self.n:,} of {self.total:,} {unit})",
            f"{_clock(now - self.t0)} elapsed",
        ]
        done, elapsed = self.n - self.start, now - self.t0
        if 0 < done and self.n < self.total and elapsed > 0:
            parts.append(f"{_clock((self.total - self.n) * elapsed / done)} left")
        parts += [f"{key} {value}" for key, value in self.postfix.items()]
        print(f"{self.desc}: {', '.join(parts)}", file=self.stream, flush=True)


def _clock(seconds: float) -> str:
    """``m:ss``, or ``h:mm:ss`` from an hour."""
    whole = int(round(seconds))
    hours, rest = divmod(whole, 3600)
    minutes, secs = divmod(rest, 60)
    return f"{hours}:{minutes:02d}:{secs:02d}" if hours else f"{minutes}:{secs:02d}"
