"""Packages that import their public names on first use (PEP 562).

A package's ``__init__`` lists where each public name lives; ``import rrls.benchmark`` then
costs nothing, and reading ``rrls.benchmark.Benchmark`` imports just the module that holds it.
This keeps the light commands light (``rrls benchmark --help`` never imports torch or
matplotlib) and lets a package's modules import one another without going through the
package's ``__init__`` and back. Nothing here imports rrls: every layer may use it.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable, Mapping
from typing import Any

__all__ = ["lazy_exports"]


def lazy_exports(
    package: str,
    where: Mapping[str, str],
    namespace: dict[str, Any],
    otherwise: Callable[[str], Any] | None = None,
) -> tuple[Callable[[str], Any], Callable[[], list[str]]]:
    """The ``__getattr__`` and ``__dir__`` of ``package``, whose public name ``n`` lives in its
    module ``where[n]``; ``namespace`` is the package's ``globals()`` (a name read once is
    stored there, so later reads are plain attribute reads). Any other name goes to
    ``otherwise`` (e.g. :func:`rrls.deprecation.moved_modules`' aliases), else it is the
    ``AttributeError`` a module raises.

    >>> import json.encoder
    >>> getattr_, dir_ = lazy_exports("json", {"JSONEncoder": "encoder"}, {})
    >>> getattr_("JSONEncoder") is json.encoder.JSONEncoder, dir_()
    (True, ['JSONEncoder'])
    """

    def getattr_(name: str) -> Any:
        if name in where:
            value = getattr(importlib.import_module(f"{package}.{where[name]}"), name)
            namespace[name] = value
            return value
        if otherwise is not None:
            return otherwise(name)
        raise AttributeError(f"module {package!r} has no attribute {name!r}")

    def dir_() -> list[str]:
        return sorted({*namespace, *where})

    return getattr_, dir_
