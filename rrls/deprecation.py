"""Old spellings that keep working while saying what replaces them.

One place for rrls's deprecations, so that every old name warns the same way: a
``DeprecationWarning`` pointing at the caller's line and naming the new spelling. Nothing here
imports rrls: every layer may use it.
"""

from __future__ import annotations

import argparse
import functools
import importlib
import importlib.abc
import importlib.util
import sys
import warnings
from collections.abc import Callable
from typing import Any, TypeVar

F = TypeVar("F", bound=Callable[..., Any])

__all__ = ["DeprecatedOption", "moved_modules", "notice", "renamed_keywords", "warn_deprecated"]


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


class _MovedModules(importlib.abc.MetaPathFinder, importlib.abc.Loader):
    """Finds a moved module's old name and hands the import its new module (the placeholder a
    loader gets is replaced in ``sys.modules``, which the import system returns): the old path
    keeps working, with a warning, and no file is left at it."""

    def __init__(self) -> None:
        self.moves: dict[str, str] = {}

    def find_spec(self, fullname: str, path: Any = None, target: Any = None) -> Any:
        if fullname not in self.moves:
            return None
        return importlib.util.spec_from_loader(fullname, self)

    def create_module(self, spec: Any) -> None:
        return None  # a plain placeholder, replaced below

    def exec_module(self, module: Any) -> None:
        new = self.moves[module.__name__]
        warn_deprecated(f"{module.__name__} is deprecated; use {new} (the same module)", 3)
        sys.modules[module.__name__] = importlib.import_module(new)


_MOVED = _MovedModules()


def moved_modules(moves: dict[str, str]) -> Callable[[str], Any]:
    """Keep the modules ``{old dotted name: new dotted name}`` importable under their old names
    (``import old``, ``from old import x``), warning each time one is first imported. Returns a
    module ``__getattr__`` for their package, so that ``package.old`` read as an attribute
    works and warns too (any other name: the ``AttributeError`` a module raises)."""
    (package,) = {old.rpartition(".")[0] for old in moves}  # one package's modules
    _MOVED.moves.update(moves)
    if _MOVED not in sys.meta_path:
        sys.meta_path.append(_MOVED)  # last: it never shadows a module that exists
    by_attribute = {old.rpartition(".")[2]: old for old in moves}

    def attribute(name: str) -> Any:
        if name in by_attribute:
            return importlib.import_module(by_attribute[name])
        raise AttributeError(f"module {package!r} has no attribute {name!r}")

    return attribute
