"""One validator for every file rrls reads: each format declares its fields once, as data, in
the module that knows the format, and every reader checks them here before using a value.

Why not JSON Schema or pydantic: the checks that matter here are outside JSON Schema's
vocabulary (Python's ``json`` reads ``NaN`` and ``1e400`` as floats, which a ``"number"``
accepts; a bool is an ``int`` to Python), pydantic would be a compiled core dependency of the
torch-free side for a dozen flat objects, and both report errors over several lines. This
module is ~200 lines, has no dependency, and says what is wrong in one line: the file, the
field, the value and what is valid::

    runs/td3-hopper-3d-seed0/result.json: field 'worst_case' is nan; valid: a finite number

>>> schema = Schema({"mesh": integer(1, 10**6), "physics": string(choices=("v5", "paper"))})
>>> schema.check({"mesh": 10, "physics": "v5"}, "benchmark.json")
{'mesh': 10, 'physics': 'v5'}
>>> schema.check({"mesh": 2.9}, "benchmark.json")
Traceback (most recent call last):
...
rrls.schema.SchemaError: benchmark.json: field 'mesh' is 2.9; valid: an integer in [1, 1000000]
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

__all__ = [
    "Field",
    "JsonError",
    "Schema",
    "SchemaError",
    "TableSchema",
    "anything",
    "array",
    "boolean",
    "integer",
    "number",
    "obj",
    "string",
]

#: the largest integer a file may hold where no narrower limit is stated (JSON's safe range)
MAX_INT = 2**53


class SchemaError(ValueError):
    """A file or object that is not what its format says (one line: file, field, value)."""


class JsonError(SchemaError):
    """JSON refused before its fields are read: not UTF-8, not JSON, too large or nested too
    deep. ``reason``: the message without the file's name (for readers that word their own);
    ``syntax``: the text is not JSON at all (a reader may then take it as plain text)."""

    def __init__(self, where: str, reason: str, syntax: bool = False) -> None:
        super().__init__(f"{where}: {reason}")
        self.where, self.reason, self.syntax = where, reason, syntax


@dataclass(frozen=True)
class Field:
    """What one field may hold. ``kind``: ``int``, ``number``, ``bool``, ``str``, ``list``,
    ``object`` or ``any``; ``null``: None allowed; ``required``: the key must be present."""

    kind: str
    low: float | None = None
    high: float | None = None
    low_open: bool = False  # ``> low`` rather than ``>= low``
    choices: tuple[Any, ...] | None = None
    items: Field | None = None
    schema: Schema | None = None
    null: bool = False
    required: bool = False
    max_items: int | None = None

    def describe(self) -> str:
        """What is valid, in words (the end of every error message)."""
        words = {
            "int": "an integer",
            "number": "a finite number",
            "bool": "true or false",
            "str": "a string",
            "object": "an object",
            "any": "any value",
        }
        if self.choices is not None:
            text = "one of " + ", ".join(repr(c) for c in self.choices)
        elif self.kind == "list":
            inner = self.items.describe() if self.items else "values"
            most = f" (at most {self.max_items})" if self.max_items is not None else ""
            text = f"a list of {_plural(inner)}{most}"
        else:
            text = words[self.kind]
            if self.kind in ("int", "number") and (self.low is not None or self.high is not None):
                text += " " + _range(self)
        return f"null or {text}" if self.null else text


def _plural(text: str) -> str:
    for a in ("an ", "a "):
        if text.startswith(a):
            rest = text[len(a) :]
            head, _, tail = rest.partition(" ")
            return f"{head}s {tail}".strip() if head[-1] != "s" else rest
    return text


def _range(f: Field) -> str:
    if f.low is not None and f.high is not None and not f.low_open:
        return f"in [{_num(f.low)}, {_num(f.high)}]"
    parts = []
    if f.low is not None:
        parts.append(f"{'>' if f.low_open else '>='} {_num(f.low)}")
    if f.high is not None:
        parts.append(f"<= {_num(f.high)}")
    return " and ".join(parts)


def _num(x: float) -> str:
    return str(int(x)) if float(x).is_integer() and abs(x) < 1e16 else repr(x)


def integer(low: float | None = 0, high: float | None = MAX_INT, **kw: Any) -> Field:
    return Field("int", low=low, high=high, **kw)


def number(low: float | None = None, high: float | None = None, **kw: Any) -> Field:
    return Field("number", low=low, high=high, **kw)


def boolean(**kw: Any) -> Field:
    return Field("bool", **kw)


def string(choices: Sequence[str] | None = None, **kw: Any) -> Field:
    return Field("str", choices=None if choices is None else tuple(choices), **kw)


def array(items: Field, max_items: int | None = 100_000, **kw: Any) -> Field:
    return Field("list", items=items, max_items=max_items, **kw)


def obj(schema: Schema | None = None, **kw: Any) -> Field:
    return Field("object", schema=schema, **kw)


def anything(**kw: Any) -> Field:
    return Field("any", **kw)


@dataclass(frozen=True)
class Schema:
    """An object's fields; ``open``: keys not declared are allowed (free-form records such as
    a policy's metadata), else refused by name."""

    fields: Mapping[str, Field]
    open: bool = False

    def check(self, data: Any, where: str, path: str = "") -> dict[str, Any]:
        """``data`` itself if it matches, else a one-line ``SchemaError`` naming ``where``
        (the file), the field and the value."""
        if not isinstance(data, Mapping):
            what = f"field {path!r} is" if path else "it holds"
            raise SchemaError(f"{where}: {what} {_show(data)}; valid: an object of fields")
        if not self.open:
            unknown = sorted(str(k) for k in data if k not in self.fields)
            if unknown:
                raise SchemaError(
                    f"{where}: unknown field {_join(path, unknown[0])!r}; valid fields: "
                    f"{', '.join(self.fields)}"
                )
        for name, spec in self.fields.items():
            if name not in data:
                if spec.required:
                    raise SchemaError(
                        f"{where}: field {_join(path, name)!r} is missing; valid: {spec.describe()}"
                    )
                continue
            _check_value(spec, data[name], where, _join(path, name))
        return dict(data)


def _join(path: str, name: str) -> str:
    return f"{path}.{name}" if path else name


def _show(value: Any) -> str:
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


def _plain(value: Any) -> Any:
    """numpy scalars (a CSV's cells) as the Python values JSON would give."""
    if type(value).__module__ == "numpy" and hasattr(value, "item"):
        return value.item()
    return value


def _check_value(spec: Field, value: Any, where: str, path: str) -> None:
    value = _plain(value)
    if value is None:
        if spec.null:
            return
        _bad(spec, value, where, path)
    kind = spec.kind
    if kind == "any":
        return
    if kind == "bool":
        if not isinstance(value, bool):
            _bad(spec, value, where, path)
    elif kind in ("int", "number"):
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            _bad(spec, value, where, path)
        if kind == "int" and not isinstance(value, int):
            _bad(spec, value, where, path)
        if isinstance(value, float) and not math.isfinite(value):
            _bad(spec, value, where, path)
        if spec.low is not None and (value <= spec.low if spec.low_open else value < spec.low):
            _bad(spec, value, where, path)
        if spec.high is not None and value > spec.high:
            _bad(spec, value, where, path)
    elif kind == "str":
        if not isinstance(value, str):
            _bad(spec, value, where, path)
    elif kind == "list":
        if isinstance(value, (str, bytes, Mapping)) or not isinstance(value, Sequence):
            _bad(spec, value, where, path)
        if spec.max_items is not None and len(value) > spec.max_items:
            raise SchemaError(
                f"{where}: field {path!r} holds {len(value)} items; valid: {spec.describe()}"
            )
        if spec.items is not None:
            for i, item in enumerate(value):
                _check_value(spec.items, item, where, f"{path}[{i}]")
    elif kind == "object":
        if spec.schema is not None:
            spec.schema.check(value, where, path)
        elif not isinstance(value, Mapping):
            _bad(spec, value, where, path)
    if spec.choices is not None and value not in spec.choices:
        _bad(spec, value, where, path)


def _bad(spec: Field, value: Any, where: str, path: str) -> None:
    raise SchemaError(f"{where}: field {path!r} is {_show(value)}; valid: {spec.describe()}")


@dataclass(frozen=True)
class TableSchema:
    """A table's header: the columns it must have and what each holds (``int``, ``number``,
    ``bool``, ``str``); other columns are allowed (a set's parameters, a split's flags)."""

    columns: Mapping[str, str]
    #: columns that may hold NaN (an episode's return when the physics diverged)
    nan: tuple[str, ...] = field(default=())

    def check(self, frame: Any, where: str) -> Any:
        """``frame`` itself if its header and column types match, else one line naming the
        file, the column and what it should hold."""
        import numpy as np
        from pandas.api import types

        missing = [c for c in self.columns if c not in frame.columns]
        if missing and len(frame.columns) == 0 and len(frame) == 0:
            return frame  # an empty table written without rows
        if missing:
            raise SchemaError(
                f"{where}: column {missing[0]!r} is missing; valid columns include "
                f"{', '.join(self.columns)}"
            )
        for name, kind in self.columns.items():
            col = frame[name]
            if not len(col):
                continue
            ok = {
                "int": types.is_integer_dtype,
                "bool": types.is_bool_dtype,
                "str": lambda c: types.is_string_dtype(c) or types.is_object_dtype(c),
                "number": lambda c: types.is_numeric_dtype(c) and not types.is_bool_dtype(c),
            }[kind](col)
            if ok and kind == "number" and name not in self.nan:
                ok = bool(np.isfinite(col.to_numpy(dtype=float)).all())
            if not ok:
                words = {"int": "integers", "bool": "true/false", "str": "text"}
                want = words.get(kind, "finite numbers" if name not in self.nan else "numbers")
                raise SchemaError(
                    f"{where}: column {name!r} holds {col.dtype} values that are not all "
                    f"{want}; valid: {want}"
                )
        return frame
