"""The entry points' protocol keywords, turned into the one :class:`Protocol` they work on.

``evaluate``, ``evaluate_dynamic`` and ``search_worst_case`` take a protocol; their keywords
(``mesh=``, ``episodes=``...) build one for interactive use, in :func:`keyword_protocol`, so
each body reads a protocol only. A keyword's default is told apart from the same value given:
beside a protocol every keyword it holds is refused once the caller passes it, whatever its
value (``mesh=10`` is refused too, though 10 is the default), since the protocol's value would
silently win. The signature still shows each default (``mesh: int | Default = Default(10)``).

>>> def points(mesh: int | Default = Default(10)) -> int:
...     return or_default(mesh)
>>> points(), points(mesh=3)
(10, 3)
>>> passed(mesh=Default(10), seed=0)
{'mesh': False, 'seed': True}
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, Generic, TypeVar

from rrls.evaluation.protocol import Protocol, check_counts, check_protocol_alone
from rrls.physics import physics_label

__all__ = ["Default", "keyword_protocol", "or_default", "passed"]

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


def keyword_protocol(
    caller: str,
    protocol: Protocol | None,
    keywords: Mapping[str, Any],
    fields: Mapping[str, str] | None = None,
    **fixed: Any,
) -> Protocol:
    """The protocol ``caller`` works on: ``protocol`` as given, refused beside any of
    ``keywords`` the caller passed (one line naming them), or else one built from ``keywords``
    (each as given or its default) and ``fixed`` (fields the caller sets itself).

    A keyword is the protocol field of its name, or ``fields[name]`` (the dynamic evaluation's
    ``episodes`` is ``dynamic_episodes``); ``paper`` is the physics as a bool and
    ``disruptors`` a mapping or None. Counts are checked first under the caller's names.
    """
    renamed = {"paper": "physics", **(fields or {})}
    if protocol is not None:
        check_protocol_alone(caller, protocol, passed(**keywords), renamed)
        return protocol
    values = {name: or_default(value) for name, value in keywords.items()}
    check_counts(**{name: values[name] for name in ("episodes", "mesh") if name in values})
    if "paper" in values:
        values["paper"] = physics_label(bool(values["paper"]))
    if "disruptors" in values:
        values["disruptors"] = tuple(dict(values["disruptors"] or {}).items())
    return Protocol(**{renamed.get(name, name): value for name, value in values.items()}, **fixed)
