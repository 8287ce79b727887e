"""How an algorithm's ``Config`` declares a hyper-parameter: its default and its help text, which
``rrls train --help`` reads (``hp``), and how a config becomes JSON (``jsonable``)."""

from __future__ import annotations

from dataclasses import field
from typing import Any

__all__ = ["hp", "jsonable"]


def hp(default: Any, help: str, **extra: Any) -> Any:  # argparse's word
    """An option's default and its ``rrls train --help`` text (the CLI reads both from here)."""
    return field(default=default, metadata={"help": help, **extra})


def jsonable(fields: dict[str, Any]) -> dict[str, Any]:
    return {k: (list(v) if isinstance(v, tuple) else v) for k, v in fields.items()}
