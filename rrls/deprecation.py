"""Old spellings that keep working while saying what replaces them.

One place for rrls's deprecations, so that every old name warns the same way: a
``DeprecationWarning`` pointing at the caller's line and naming the new spelling. Nothing here
imports rrls: every layer may use it.
"""

from __future__ import annotations

import functools
import warnings
from collections.abc import Callable
from typing import Any, TypeVar

F = TypeVar("F", bound=Callable[..., Any])

__all__ = ["renamed_keywords", "warn_deprecated"]


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
