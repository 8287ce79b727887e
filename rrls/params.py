"""Physical parameters as data.

A :class:`Parameter` is one row of a task's parameter table: the user-facing name (kept from the
original RRLS code), the MuJoCo field it writes and the body, geom, joint or actuator it
targets, looked up *by name* in the compiled model. Adding a parameter to a task means adding a
row; the generic robust environment (:mod:`rrls.envs.base`) knows how to read, validate and write
every field below, and :func:`rrls.register_task` checks every row against the compiled model.

Fields understood (``FIELDS`` holds units and valid ranges; docs/concepts.md has the same table):

``body_mass``
    ``model.body_mass[body]`` (kg). MuJoCo's derived constants (subtree masses, ``dof_M0``, the
    constraint inverse weights) are refreshed with ``mj_setConst`` afterwards; with
    ``scale_inertia=True`` the body's inertia is scaled by the same factor as its mass.
``geom_friction``
    the sliding friction ``model.geom_friction[:, 0]`` of every geom (target ``ALL_GEOMS``) or of
    one named geom. MuJoCo gives a contact the larger friction of its two geoms, so writing only
    the floor does nothing where a foot has a larger friction (Hopper 2.0, Walker 1.9): writing
    every geom makes every contact's sliding friction equal to the value. The nominal value of
    ``ALL_GEOMS`` is the floor's.
``body_friction``
    the sliding friction ``geom_friction[g, 0]`` of every geom ``g`` of one body (its nominal
    value is the body's first geom's). Inert below the friction of what the body touches: MuJoCo
    gives a contact the larger friction of its two geoms, so Hopper's ``footfriction`` at 0.1,
    0.5 or 0.9 gives the same episodes as at 1.0, the floor's. To go below, lower the floor
    first: ``set_params(worldfriction=0.1, footfriction=0.5)`` (in that order).
``body_ipos``
    the offset (m, in the body frame) of the body's centre of mass from the model's own
    (``body_ipos[body, component] = nominal + value``; nominal value 0). ``mj_setConst`` follows.
``dof_damping`` / ``dof_armature`` / ``dof_frictionloss``
    the joint's damping (N·m·s/rad for a hinge, N·s/m for a slide), armature (rotor inertia
    added to the joint: kg·m² / kg; ``mj_setConst`` follows) and dry friction (N·m / N). The
    target is a hinge or slide joint (one degree of freedom).
``actuator_gear``
    the gear (strength) ``actuator_gear[a, 0]`` of the actuator, named, or found by the joint
    it drives (Gymnasium's XMLs leave most actuators unnamed). A motor's force is ``gear * ctrl``.
``opt_gravity``
    the magnitude of gravity (m/s²): ``model.opt.gravity[2] = -value`` (target ``""``).
``opt_timestep``
    the integration step (s): ``model.opt.timestep``. Gymnasium's ``env.dt`` is
    ``frame_skip * timestep``, so a step of the env spans more or less simulated time; velocities
    in rewards are divided by the new ``dt`` (they stay velocities).
``opt_viscosity``
    the viscosity of the medium (Pa·s): ``model.opt.viscosity`` (Swimmer's water).
``xfrc_applied``
    a Cartesian force (world frame, N) on the body's centre of mass, component ``component``
    (0: x, 1: y, 2: z). Lives in ``mjData``, so it is re-applied after every reset.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Literal, NamedTuple

import numpy as np

from rrls.deprecation import warn_deprecated

if TYPE_CHECKING:  # mujoco is imported lazily: `import rrls` must stay cheap
    import mujoco

Field = Literal[
    "body_mass",
    "geom_friction",
    "body_friction",
    "body_ipos",
    "dof_damping",
    "dof_armature",
    "dof_frictionloss",
    "actuator_gear",
    "opt_gravity",
    "opt_timestep",
    "opt_viscosity",
    "xfrc_applied",
]

#: target of a parameter that applies to every geom of the model.
ALL_GEOMS = "*"


class FieldInfo(NamedTuple):
    """What a field is, for validation, errors and the table of docs/concepts.md."""

    what: str  #: "mass", "friction", ... (used in error messages)
    mujoco: str  #: the MuJoCo field written
    units: str
    low: float
    low_inclusive: bool
    high: float
    target: str  #: what ``target`` names: "body", "geom", "joint", "actuator" or "model"


#: every field, its units and valid range. Upper limits are far beyond physical values but below
#: where MuJoCo overflows (``worldfriction=1e300`` gives NaN observations; 1e8 steps finitely).
FIELDS: dict[str, FieldInfo] = {
    "body_mass": FieldInfo("mass", "body_mass[b]", "kg", 0.0, False, 1e9, "body"),
    "geom_friction": FieldInfo("friction", "geom_friction[g, 0]", "-", 0.0, True, 1e6, "geom"),
    "body_friction": FieldInfo(
        "friction",
        "geom_friction[g, 0] (the body's geoms; inert below the friction of the geom touched)",
        "-",
        0.0,
        True,
        1e6,
        "body",
    ),
    "body_ipos": FieldInfo(
        "centre-of-mass offset", "body_ipos[b, k] (+ nominal)", "m", -10.0, True, 10.0, "body"
    ),
    "dof_damping": FieldInfo(
        "damping", "dof_damping[d]", "N·m·s/rad (slide: N·s/m)", 0.0, True, 1e6, "joint"
    ),
    "dof_armature": FieldInfo(
        "armature", "dof_armature[d]", "kg·m² (slide: kg)", 0.0, True, 1e6, "joint"
    ),
    "dof_frictionloss": FieldInfo(
        "dry friction", "dof_frictionloss[d]", "N·m (slide: N)", 0.0, True, 1e6, "joint"
    ),
    "actuator_gear": FieldInfo(
        "gear", "actuator_gear[a, 0]", "N·m per unit control (slide: N)", 0.0, True, 1e6, "actuator"
    ),
    "opt_gravity": FieldInfo("gravity", "opt.gravity[2] = -value", "m/s²", 0.0, True, 1e3, "model"),
    "opt_timestep": FieldInfo("timestep", "opt.timestep", "s", 0.0, False, 0.1, "model"),
    "opt_viscosity": FieldInfo("viscosity", "opt.viscosity", "Pa·s", 0.0, True, 1e3, "model"),
    "xfrc_applied": FieldInfo(
        "force", "xfrc_applied[b, k]", "N", -math.inf, True, math.inf, "body"
    ),
}

#: fields whose change needs MuJoCo's derived constants recomputed (``mj_setConst``)
SETCONST_FIELDS = frozenset({"body_mass", "body_ipos", "dof_armature", "actuator_gear"})

#: kind name -> the fields it covers, for ``get_params(kinds=...)``
KINDS: dict[str, tuple[str, ...]] = {
    "mass": ("body_mass",),
    "friction": ("geom_friction", "body_friction"),
    "com": ("body_ipos",),
    "damping": ("dof_damping",),
    "armature": ("dof_armature",),
    "frictionloss": ("dof_frictionloss",),
    "gear": ("actuator_gear",),
    "gravity": ("opt_gravity",),
    "timestep": ("opt_timestep",),
    "viscosity": ("opt_viscosity",),
    "force": ("xfrc_applied",),
}
#: the original RRLS code's kinds (masses, ``worldfriction``, forces): what ``get_params()``
#: returns without arguments, so code written for the original runs unchanged
ORIGINAL_FIELDS = frozenset({"body_mass", "geom_friction", "xfrc_applied"})


def kind_fields(kinds: object) -> frozenset[str] | None:
    """The fields ``get_params(kinds=...)`` returns: None for every field (``"all"``), the
    original code's for ``None``/``"original"``, else those of the named kinds (a name or an
    iterable of names of :data:`KINDS`); an unknown name is a ``ValueError`` listing the valid."""
    if kinds is None or kinds == "original":
        return ORIGINAL_FIELDS
    if kinds == "all":
        return None
    names = [kinds] if isinstance(kinds, str) else list(kinds)  # type: ignore[call-overload]
    unknown = [k for k in names if k not in KINDS]
    if unknown:
        raise ValueError(
            f"unknown parameter kind(s) {unknown}; valid: 'all', 'original' or any of "
            f"{', '.join(KINDS)}"
        )
    return frozenset(f for k in names for f in KINDS[k])


@dataclass(frozen=True)
class Parameter:
    """One physical parameter: ``name`` writes ``field`` of ``target``.

    ``target`` is a body name (``"<body>/child"`` for the only child body of a named body: Ant's
    ankles are unnamed in Gymnasium's XML), a geom name or :data:`ALL_GEOMS`, a joint name, an
    actuator name (or the name of the joint it drives), or ``""`` for model options (gravity,
    timestep). ``component`` is the axis of forces and centre-of-mass offsets (0: x, 1: y, 2: z).
    ``aliases`` are extra names accepted by ``set_params``.
    """

    name: str
    field: Field
    target: str = ""
    component: int = 0
    aliases: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        if self.field not in FIELDS:
            raise ValueError(
                f"parameter {self.name!r}: unknown field {self.field!r}; valid: {', '.join(FIELDS)}"
            )
        if not (isinstance(self.name, str) and self.name.isidentifier()):
            raise ValueError(f"parameter name must be an identifier, got {self.name!r}")
        if self.component not in (0, 1, 2):
            raise ValueError(f"parameter {self.name!r}: component must be 0, 1 or 2")

    @property
    def info(self) -> FieldInfo:
        return FIELDS[self.field]

    def resolve(self, model: mujoco.MjModel) -> np.ndarray:
        """Indices into the field's first axis, looked up by name in ``model``.

        A bad name raises a ``KeyError`` naming the valid ones.
        """
        field = self.field
        if field == "geom_friction":
            if self.target != ALL_GEOMS:
                return np.array([_named_id(model, "geom", self.target)])
            return np.arange(model.ngeom)
        if field == "body_friction":
            geoms = np.flatnonzero(model.geom_bodyid == body_id(model, self.target))
            if not len(geoms):
                raise KeyError(f"body {self.target!r} has no geom, so no friction")
            return geoms
        if field == "body_ipos":
            b = body_id(model, self.target)
            if model.body_simple[b]:
                movable = [
                    n for n in names_of(model, "body") if not model.body_simple[body_id(model, n)]
                ]
                raise KeyError(
                    f"body {self.target!r} is compiled as 'simple' (its frame is its centre of "
                    f"mass), so MuJoCo cannot move its centre of mass; bodies that can: "
                    f"{', '.join(movable)}"
                )
            return np.array([b])
        if field in ("dof_damping", "dof_armature", "dof_frictionloss"):
            return np.array([joint_dof(model, self.target)])
        if field == "actuator_gear":
            return np.array([actuator_id(model, self.target)])
        if field.startswith("opt_"):
            return np.zeros(0, dtype=np.int64)
        return np.array([body_id(model, self.target)])

    def check(self, value: float) -> str | None:
        """Why ``value`` is not acceptable for this parameter, or None."""
        if type(value) is not float and (  # fast path: the adversary sets floats every step
            not isinstance(value, (int, float, np.integer, np.floating)) or isinstance(value, bool)
        ):
            return f"{self.name} must be a real number, got {value!r}"
        if not math.isfinite(value):
            return f"{self.name} must be finite, got {value!r}"
        info = FIELDS[self.field]
        if value < info.low or (value == info.low and not info.low_inclusive):
            op = ">=" if info.low_inclusive else ">"
            article = "an" if info.what[0] in "aeiou" else "a"
            return (
                f"{self.name} is {article} {info.what} and must be {op} {info.low:g}, got {value!r}"
            )
        if value > info.high:
            return f"{self.name} must be <= {info.high:g} ({info.what}), got {value!r}"
        return None


# -- lookups by name ------------------------------------------------------------------------------
_OBJ = {
    "body": "mjOBJ_BODY",
    "geom": "mjOBJ_GEOM",
    "joint": "mjOBJ_JOINT",
    "actuator": "mjOBJ_ACTUATOR",
}
_COUNT = {"body": "nbody", "geom": "ngeom", "joint": "njnt", "actuator": "nu"}


def names_of(model: mujoco.MjModel, kind: str) -> list[str]:
    """The named bodies / geoms / joints / actuators of ``model`` (for error messages)."""
    import mujoco

    obj = getattr(mujoco.mjtObj, _OBJ[kind])
    names = (mujoco.mj_id2name(model, obj, i) for i in range(getattr(model, _COUNT[kind])))
    return [n for n in names if n]


def _named_id(model: mujoco.MjModel, kind: str, name: str) -> int:
    import mujoco

    i = mujoco.mj_name2id(model, getattr(mujoco.mjtObj, _OBJ[kind]), name)
    if i < 0:
        valid = ", ".join(names_of(model, kind)) or "none"
        plural = "bodies" if kind == "body" else f"{kind}s"
        raise KeyError(f"no {kind} named {name!r} in the model; valid {plural}: {valid}")
    return i


def body_id(model: mujoco.MjModel, ref: str) -> int:
    """Body index of ``ref`` (a body name, or ``"<name>/child"`` for its only child)."""
    name, _, child = ref.partition("/")
    parent = _named_id(model, "body", name)
    if not child:
        return parent
    if child != "child":
        raise ValueError(f"bad body reference {ref!r}: use '<body>' or '<body>/child'")
    children = np.flatnonzero(model.body_parentid == parent)
    children = children[children != parent]  # the world body is its own parent
    if len(children) != 1:
        raise KeyError(f"body {name!r} has {len(children)} children, expected exactly one")
    return int(children[0])


def joint_dof(model: mujoco.MjModel, name: str) -> int:
    """The degree of freedom of the hinge or slide joint ``name``."""
    import mujoco

    j = _named_id(model, "joint", name)
    one_dof_types = (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE))
    if int(model.jnt_type[j]) not in one_dof_types:
        one_dof = [
            n
            for n in names_of(model, "joint")
            if int(model.jnt_type[_named_id(model, "joint", n)]) in one_dof_types
        ]
        raise KeyError(
            f"joint {name!r} is a free or ball joint; joint rows take a hinge or slide joint: "
            f"{', '.join(one_dof)}"
        )
    return int(model.jnt_dofadr[j])


def actuator_id(model: mujoco.MjModel, ref: str) -> int:
    """The actuator named ``ref``, else the one actuator driving the joint named ``ref``."""
    import mujoco

    a = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_ACTUATOR, ref)
    if a >= 0:
        return a
    j = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, ref)
    joint_trn = (int(mujoco.mjtTrn.mjTRN_JOINT), int(mujoco.mjtTrn.mjTRN_JOINTINPARENT))
    driving = [
        i
        for i in range(model.nu)
        if j >= 0
        and int(model.actuator_trntype[i]) in joint_trn
        and model.actuator_trnid[i, 0] == j
    ]
    if len(driving) == 1:
        return driving[0]
    valid = names_of(model, "actuator") + [
        mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_JOINT, int(model.actuator_trnid[i, 0]))
        for i in range(model.nu)
        if int(model.actuator_trntype[i]) in joint_trn
    ]
    raise KeyError(
        f"no actuator named {ref!r} nor driving a joint of that name; valid: "
        f"{', '.join(dict.fromkeys(v for v in valid if v)) or 'none'}"
    )


# -- rows for common kinds ------------------------------------------------------------------------
def mass_params(parts: dict[str, str]) -> tuple[Parameter, ...]:
    """``<part>mass`` rows for ``{part name: body reference}``."""
    return tuple(Parameter(f"{part}mass", "body_mass", body) for part, body in parts.items())


def force_params(parts: dict[str, str], planar: bool) -> tuple[Parameter, ...]:
    """``<part>force_x/_y/_z`` rows for ``{part name: body reference}``.

    On planar tasks every joint moves in the world x-z plane, so a force along world y does
    nothing: there ``_y`` writes the vertical axis (world z) and ``_z`` is an alias of ``_y``.
    """
    rows: list[Parameter] = []
    for part, body in parts.items():
        rows.append(Parameter(f"{part}force_x", "xfrc_applied", body, 0))
        if planar:
            rows.append(Parameter(f"{part}force_y", "xfrc_applied", body, 2, (f"{part}force_z",)))
        else:
            rows.append(Parameter(f"{part}force_y", "xfrc_applied", body, 1))
            rows.append(Parameter(f"{part}force_z", "xfrc_applied", body, 2))
    return tuple(rows)


def friction_params(parts: dict[str, str]) -> tuple[Parameter, ...]:
    """``<part>friction`` rows (sliding friction of every geom of the body)."""
    return tuple(Parameter(f"{p}friction", "body_friction", b) for p, b in parts.items())


def com_params(parts: dict[str, str], planar: bool) -> tuple[Parameter, ...]:
    """``<part>com_x/_y/_z`` rows: centre-of-mass offsets in the body frame (m).

    Planar tasks get ``_x`` and ``_z`` only (an offset out of the x-z plane changes nothing).
    """
    axes = ((0, "x"), (2, "z")) if planar else ((0, "x"), (1, "y"), (2, "z"))
    return tuple(
        Parameter(f"{p}com_{a}", "body_ipos", b, k) for p, b in parts.items() for k, a in axes
    )


def joint_params(
    joints: dict[str, str], kinds: tuple[str, ...] = ("damping", "armature", "frictionloss")
) -> tuple[Parameter, ...]:
    """``<part>damping`` / ``<part>armature`` / ``<part>frictionloss`` rows for
    ``{part name: hinge or slide joint name}``."""
    return tuple(
        Parameter(f"{p}{kind}", f"dof_{kind}", j)  # type: ignore[arg-type]
        for kind in kinds
        for p, j in joints.items()
    )


def gear_params(actuators: dict[str, str]) -> tuple[Parameter, ...]:
    """``<part>gear`` rows for ``{part name: actuator name or the joint it drives}``."""
    return tuple(Parameter(f"{p}gear", "actuator_gear", a) for p, a in actuators.items())


GRAVITY = Parameter("gravity", "opt_gravity")
TIMESTEP = Parameter("timestep", "opt_timestep")
VISCOSITY = Parameter("viscosity", "opt_viscosity")


def physics_params(
    bodies: dict[str, str],
    joints: dict[str, str],
    actuators: dict[str, str] | None = None,
    planar: bool = False,
    friction: bool = True,
    com: dict[str, str] | None = None,
) -> tuple[Parameter, ...]:
    """Every kind beyond masses, for a task's parts: per-body friction (unless ``friction`` is
    False: a model without contacts) and centre-of-mass offsets, joint damping / armature / dry
    friction, actuator gear, gravity and timestep.

    ``actuators`` defaults to ``joints`` (each joint driven by one actuator); ``com`` (the
    bodies with centre-of-mass rows) to ``bodies``.
    """
    return (
        (friction_params(bodies) if friction else ())
        + com_params(bodies if com is None else com, planar)
        + joint_params(joints)
        + gear_params(joints if actuators is None else actuators)
        + (GRAVITY, TIMESTEP)
    )


def check_bounds(specs: tuple[Parameter, ...], box: object) -> None:
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


__all__ = [
    "actuator_id",
    "ALL_GEOMS",
    "body_id",
    "check_bounds",
    "com_params",
    "Field",
    "FieldInfo",
    "FIELDS",
    "force_params",
    "friction_params",
    "gear_params",
    "GRAVITY",
    "joint_dof",
    "joint_params",
    "kind_fields",
    "KINDS",
    "mass_params",
    "names_of",
    "ORIGINAL_FIELDS",
    "Parameter",
    "physics_params",
    "SETCONST_FIELDS",
    "TIMESTEP",
    "VISCOSITY",
]


def __getattr__(name: str) -> Any:
    """``ParamSpec``: :class:`Parameter`'s former name (deprecated: it read as
    ``typing.ParamSpec``, and as one of the unrelated ``*Spec`` classes of rrls)."""
    if name == "ParamSpec":
        warn_deprecated(
            "rrls.params.ParamSpec is deprecated; use rrls.params.Parameter (the same class)"
        )
        return Parameter
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
