"""A keyword's default told apart from the same value given: beside ``protocol=`` every keyword
the protocol holds is refused once the caller passes it, whatever its value (``mesh=10`` is
refused too, though 10 is the default), since the protocol's value would silently win.

The signature still shows each default (``mesh: int | Default = Default(10)``), and
the function reads it with :func:`or_default` where no protocol is given.

>>> def points(mesh: int | Default = Default(10)) -> int:
...     return or_default(mesh)
>>> points(), points(mesh=3)
(10, 3)
>>> passed(mesh=Default(10), seed=0)
{'mesh': False, 'seed': True}
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Generic, TypeVar

__all__ = ["Default", "or_default", "passed"]

T = TypeVar("T")


@dataclass(frozen=True)
class Default(Generic[T]):
    """A keyword's default value, marked as not passed by the caller (frozen: one instance is
    every call's default)."""

    value: T

    def __repr__(self) -> str:
        return f"Default({self.value!r})"


def or_default(argument: T | Default[T]) -> T:
    """The argument as given, or its default."""
    return argument.value if isinstance(argument, Default) else argument


def passed(**arguments: Any) -> dict[str, bool]:
    """Per keyword, whether the caller passed it (whatever the value)."""
    return {name: not isinstance(argument, Default) for name, argument in arguments.items()}
