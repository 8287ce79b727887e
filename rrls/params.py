"""Physical parameters as data.

A :class:`ParamSpec` is one row of a task's parameter table: the user-facing name (kept from the
original RRLS code), the MuJoCo field it writes and the body or geom it targets, looked up *by
name* in the compiled model. Adding a parameter to a task means adding a row; the generic robust
environment (:mod:`rrls.envs.base`) knows how to read, validate and write every field below.

Fields understood:

``body_mass``
    ``model.body_mass[body]``. MuJoCo's derived constants (subtree masses, ``dof_M0``, the
    constraint inverse weights) are refreshed with ``mj_setConst`` afterwards; with
    ``scale_inertia=True`` the body's inertia is scaled by the same factor as its mass.
``geom_friction``
    the sliding friction ``model.geom_friction[:, 0]`` of every geom (target ``ALL_GEOMS``).
    MuJoCo gives a contact the larger friction of its two geoms, so writing only the floor does
    nothing where a foot has a larger friction (Hopper 2.0, Walker 1.9): writing every geom makes
    every contact's sliding friction equal to the value. The nominal value is the floor's.
``xfrc_applied``
    a Cartesian force (world frame) on the body's centre of mass, component ``component``
    (0: x, 1: y, 2: z). Lives in ``mjData``, so it is re-applied after every reset.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Literal

import numpy as np

if TYPE_CHECKING:  # mujoco is imported lazily: `import rrls` must stay cheap
    import mujoco

Field = Literal["body_mass", "geom_friction", "xfrc_applied"]

#: target of a parameter that applies to every geom of the model.
ALL_GEOMS = "*"

#: lower limit (exclusive / inclusive) of each field, for validation
_MIN_VALUE: dict[str, tuple[float, bool]] = {
    "body_mass": (0.0, False),  # mass must be > 0
    "geom_friction": (0.0, True),  # friction must be >= 0
}
#: upper limit of each field: far beyond any physical value, below where MuJoCo overflows
#: (``worldfriction=1e300`` gives NaN observations; 1e8 still steps finitely)
_MAX_VALUE: dict[str, float] = {"body_mass": 1e9, "geom_friction": 1e6}


@dataclass(frozen=True)
class ParamSpec:
    """One physical parameter: ``name`` writes ``field`` of ``target``.

    ``target`` is a body name, ``"<body>/child"`` for the only child body of a named body (Ant's
    ankles are unnamed in Gymnasium's XML) or :data:`ALL_GEOMS`. ``aliases`` are extra names
    accepted by ``set_params``.
    """

    name: str
    field: Field
    target: str
    component: int = 0
    aliases: tuple[str, ...] = ()

    def resolve(self, model: mujoco.MjModel) -> np.ndarray:
        """Indices into the field's first axis, looked up by name in ``model``."""
        if self.field == "geom_friction":
            if self.target != ALL_GEOMS:
                return np.array([_geom_id(model, self.target)])
            return np.arange(model.ngeom)
        return np.array([body_id(model, self.target)])

    def check(self, value: float) -> str | None:
        """Why ``value`` is not acceptable for this parameter, or None."""
        if type(value) is not float and (  # fast path: the adversary sets floats every step
            not isinstance(value, (int, float, np.integer, np.floating)) or isinstance(value, bool)
        ):
            return f"{self.name} must be a real number, got {value!r}"
        if not math.isfinite(value):
            return f"{self.name} must be finite, got {value!r}"
        limit = _MIN_VALUE.get(self.field)
        if limit is not None:
            low, inclusive = limit
            if value < low or (value == low and not inclusive):
                what = "mass" if self.field == "body_mass" else "friction"
                op = ">=" if inclusive else ">"
                return f"{self.name} is a {what} and must be {op} {low}, got {value!r}"
        high = _MAX_VALUE.get(self.field)
        if high is not None and value > high:
            return f"{self.name} must be <= {high:g} (beyond it MuJoCo overflows), got {value!r}"
        return None


def body_id(model: mujoco.MjModel, ref: str) -> int:
    """Body index of ``ref`` (a body name, or ``"<name>/child"`` for its only child)."""
    import mujoco

    name, _, child = ref.partition("/")
    parent = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, name)
    if parent < 0:
        raise KeyError(f"no body named {name!r} in the model")
    if not child:
        return parent
    if child != "child":
        raise ValueError(f"bad body reference {ref!r}: use '<body>' or '<body>/child'")
    children = np.flatnonzero(model.body_parentid == parent)
    children = children[children != parent]  # the world body is its own parent
    if len(children) != 1:
        raise KeyError(f"body {name!r} has {len(children)} children, expected exactly one")
    return int(children[0])


def _geom_id(model: mujoco.MjModel, name: str) -> int:
    import mujoco

    gid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, name)
    if gid < 0:
        raise KeyError(f"no geom named {name!r} in the model")
    return gid


def mass_params(parts: dict[str, str]) -> tuple[ParamSpec, ...]:
    """``<part>mass`` rows for ``{part name: body reference}``."""
    return tuple(ParamSpec(f"{part}mass", "body_mass", body) for part, body in parts.items())


def force_params(parts: dict[str, str], planar: bool) -> tuple[ParamSpec, ...]:
    """``<part>force_x/_y/_z`` rows for ``{part name: body reference}``.

    On planar tasks every joint moves in the world x-z plane, so a force along world y does
    nothing: there ``_y`` writes the vertical axis (world z) and ``_z`` is an alias of ``_y``.
    """
    rows: list[ParamSpec] = []
    for part, body in parts.items():
        rows.append(ParamSpec(f"{part}force_x", "xfrc_applied", body, 0))
        if planar:
            rows.append(ParamSpec(f"{part}force_y", "xfrc_applied", body, 2, (f"{part}force_z",)))
        else:
            rows.append(ParamSpec(f"{part}force_y", "xfrc_applied", body, 1))
            rows.append(ParamSpec(f"{part}force_z", "xfrc_applied", body, 2))
    return tuple(rows)


def check_bounds(specs: tuple[ParamSpec, ...], box: object) -> None:
    """Refuse a box (``names``, ``low``, ``high``) whose bounds are not physical values.

    So a set such as ``torsomass in (-1, 2)`` fails where it is built, not episodes later.
    """
    by_name = {s.name: s for s in specs} | {a: s for s in specs for a in s.aliases}
    for name, low, high in zip(box.names, box.low, box.high):  # type: ignore[attr-defined]
        spec = by_name.get(name)
        if spec is None:
            continue  # unknown names are reported by the caller, with the valid ones
        for bound in (float(low), float(high)):
            problem = spec.check(bound)
            if problem:
                raise ValueError(f"uncertainty set bound out of range: {problem}")
