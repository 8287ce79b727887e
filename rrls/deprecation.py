"""Old spellings that keep working while saying what replaces them.

One place for rrls's deprecations, so that every old name warns the same way: a
``DeprecationWarning`` pointing at the caller's line and naming the new spelling. Nothing here
imports rrls: every layer may use it.
"""

from __future__ import annotations

import argparse
import functools
import sys
import warnings
from collections.abc import Callable
from typing import Any, TypeVar

F = TypeVar("F", bound=Callable[..., Any])

__all__ = ["DeprecatedOption", "notice", "renamed_keywords", "warn_deprecated"]


def warn_deprecated(message: str, stacklevel: int = 2) -> None:
    """A ``DeprecationWarning`` at the caller's caller (``stacklevel`` as in ``warnings.warn``,
    counted from the function that calls this one)."""
    warnings.warn(message, DeprecationWarning, stacklevel=stacklevel + 1)


def renamed_keywords(**renames: str) -> Callable[[F], F]:
    """Decorator: ``old="new"`` keeps ``f(old=...)`` working as ``f(new=...)`` with a
    ``DeprecationWarning``; giving both is a ``TypeError`` (which one was meant is unknown).

    >>> @renamed_keywords(nb_mesh_dim="mesh")
    ... def points(mesh: int = 10) -> int:
    ...     return mesh
    >>> import warnings
    >>> with warnings.catch_warnings(record=True) as caught:
    ...     warnings.simplefilter("always")
    ...     points(nb_mesh_dim=3), str(caught[0].message)
    (3, 'points(nb_mesh_dim=...) is deprecated; use mesh=...')
    """

    def decorate(func: F) -> F:
        @functools.wraps(func)
        def wrapper(*args: Any, **kwargs: Any) -> Any:
            for old, new in renames.items():
                if old not in kwargs:
                    continue
                if new in kwargs:
                    raise TypeError(
                        f"{func.__name__}() got both {old}= (deprecated) and {new}=; give {new}="
                    )
                warn_deprecated(f"{func.__name__}({old}=...) is deprecated; use {new}=...")
                kwargs[new] = kwargs.pop(old)
            return func(*args, **kwargs)

        return wrapper  # type: ignore[return-value]

    return decorate


def notice(command: str, message: str) -> None:
    """One line on stderr for a command-line user, who never sees a ``DeprecationWarning``
    (Python hides them outside ``__main__``): ``rrls COMMAND: warning: MESSAGE``."""
    print(f"rrls {command}: warning: {message}", file=sys.stderr)


class DeprecatedOption(argparse.Action):
    """An old flag kept as a hidden alias: stores like the new one (same ``dest``), with a
    one-line notice naming it. ``add_argument("--jobs", dest="workers", type=int,
    action=DeprecatedOption, new="--workers")``."""

    def __init__(self, option_strings: list[str], dest: str, new: str, **kwargs: Any) -> None:
        kwargs["help"] = argparse.SUPPRESS  # not in --help: one spelling is advertised
        kwargs.setdefault("default", argparse.SUPPRESS)  # never overwrites the new flag's
        super().__init__(option_strings, dest, **kwargs)
        self.new = new

    def __call__(
        self,
        parser: argparse.ArgumentParser,
        namespace: argparse.Namespace,
        values: Any,
        option_string: str | None = None,
    ) -> None:
        command = parser.prog.removeprefix("rrls ").strip() or "rrls"
        notice(command, f"{option_string} is deprecated; use {self.new} (same meaning)")
        setattr(namespace, self.dest, values)
