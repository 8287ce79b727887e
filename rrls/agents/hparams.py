"""How an algorithm's ``Config`` declares a hyper-parameter: its default and its help text, which
``rrls train --help`` reads (``hp``), the largest value it accepts (``most``: sizes are bounded
before anything is allocated), and how a config becomes JSON (``jsonable``)."""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import field, fields
from typing import Any

#: the sizes a run may ask for (checked before anything is allocated; the memory they take
#: together is checked against the machine's by ``rrls.agents.loop``)
MAX_BATCH = 1_000_000
MAX_BUFFER = 10**9
MAX_WIDTH = 65_536
MAX_LAYERS = 64

__all__ = [
    "MAX_BATCH",
    "MAX_BUFFER",
    "MAX_LAYERS",
    "MAX_WIDTH",
    "check_limits",
    "check_memory",
    "hp",
    "jsonable",
    "machine_memory",
    "most_threads",
]


def hp(
    default: Any, help: str, *, most: int | Callable[[], int] | None = None, **extra: Any
) -> Any:
    """An option's default and its ``rrls train --help`` text (the CLI reads both from here);
    ``most``: the largest value (or each entry of a tuple) accepted, or a function of the
    machine giving it."""
    meta = {"help": help, **extra}
    if most is not None:
        meta["most"] = most
    return field(default=default, metadata=meta)


def check_limits(config: Any) -> None:
    """Refuse, in one line naming the field, a value above its declared ``most`` (each entry
    of a tuple), or a tuple longer than its ``most_items``."""
    for f in fields(config):
        most = f.metadata.get("most")
        value = getattr(config, f.name)
        if value is None:
            continue
        items = f.metadata.get("most_items")
        if items is not None and len(value) > items:
            raise ValueError(f"{f.name} must have at most {items} entries, got {len(value)}")
        if most is None:
            continue
        limit = most() if callable(most) else most
        values = value if isinstance(value, (tuple, list)) else (value,)
        if any(v > limit for v in values):
            raise ValueError(f"{f.name} must be at most {limit:,}, got {value}")


def most_threads() -> int:
    """Threads a run may ask for: 4 per core of this machine (more never helps; torch crashes
    on tens of thousands)."""
    return 4 * max(os.cpu_count() or 1, 1)


def machine_memory() -> int:
    """This machine's physical memory in bytes (0 where the system does not say)."""
    try:
        return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (ValueError, OSError, AttributeError):
        return 0


def check_memory(need: int, what: str, advice: str) -> None:
    """Refuse, before allocating, what cannot fit in this machine's memory (one line)."""
    have = machine_memory()
    if have and need > have:
        raise MemoryError(
            f"{what} need about {need / 2**30:,.1f} GiB, more than this machine's "
            f"{have / 2**30:,.1f} GiB of memory; {advice}"
        )


def jsonable(fields: dict[str, Any]) -> dict[str, Any]:
    return {k: (list(v) if isinstance(v, tuple) else v) for k, v in fields.items()}
