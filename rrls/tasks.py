"""The six tasks as data: which Gymnasium v5 env, which parameters, which uncertainty sets.

Parameter names are the original RRLS code's (``torsomass``, ``frontleftlegauxmass``, ...); each
maps to a body *by name* in Gymnasium's XML (paper Appendix A). Uncertainty sets are the paper's
Table 2 (M2TD3 sets, ``1d``/``2d``/``3d``) and Table 3 (RARL force sets, ``rarl``, bounds +-3).
Nominal values are never written here: they are read from the compiled model.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from rrls.params import ALL_GEOMS, ParamSpec, force_params, mass_params

Bounds = dict[str, tuple[float, float]]


@dataclass(frozen=True)
class TaskSpec:
    key: str  #: short name used in ids and the CLI: "hopper"
    name: str  #: class-name stem: "Hopper" -> RobustHopper, ForceHopper
    v5_id: str  #: the Gymnasium env it is built on
    planar: bool  #: every joint moves in the world x-z plane (forces' ``_y`` is vertical)
    params: tuple[ParamSpec, ...]  #: robust env parameters (masses, friction)
    forces: tuple[ParamSpec, ...]  #: force env parameters
    sets: dict[str, Bounds] = field(default_factory=dict)  #: "1d", "2d", "3d", "rarl"
    #: env family of each set: "robust" (parameters of ``params``) or "force" (of ``forces``)
    families: dict[str, str] = field(default_factory=dict)

    def family_of(self, names: tuple[str, ...] | list[str]) -> str:
        """The family whose parameter table holds every name (``"robust"`` if there are none)."""
        for family, specs in (("robust", self.params), ("force", self.forces)):
            valid = {s.name for s in specs} | {a for s in specs for a in s.aliases}
            if all(n in valid for n in names):
                return family
        robust = ", ".join(s.name for s in self.params)
        forces = ", ".join(s.name for s in self.forces)
        raise ValueError(
            f"parameters {list(names)} are not all of one family of task {self.key!r}; "
            f"robust parameters: {robust}; force parameters: {forces}"
        )


WORLD_FRICTION = ParamSpec("worldfriction", "geom_friction", ALL_GEOMS)


def _rarl(*names: str) -> Bounds:
    return {name: (-3.0, 3.0) for name in names}


def _task(
    key: str,
    name: str,
    cls: str,
    planar: bool,
    parts: dict[str, str],
    sets: dict[str, Bounds],
    friction: bool,
    force_parts: dict[str, str] | None = None,
) -> TaskSpec:
    params = ((WORLD_FRICTION,) if friction else ()) + mass_params(parts)
    forces = force_params(force_parts or parts, planar)
    spec = TaskSpec(
        key=key,
        name=name,
        v5_id=f"{cls.removesuffix('Env')}-v5",
        planar=planar,
        params=params,
        forces=forces,
    )
    # each set's family is read from the parameter tables (a set mixing families is refused)
    families = {set_name: spec.family_of(tuple(bounds)) for set_name, bounds in sets.items()}
    return TaskSpec(**{**spec.__dict__, "sets": sets, "families": families})


_ANT_PARTS = {
    "torso": "torso",
    "frontleftleg": "front_left_leg",
    "frontleftlegaux": "aux_1",
    "frontleftlegankle": "aux_1/child",
    "frontrightleg": "front_right_leg",
    "frontrightlegaux": "aux_2",
    "frontrightlegankle": "aux_2/child",
    "backleftleg": "back_leg",
    "backleftlegaux": "aux_3",
    "backleftlegankle": "aux_3/child",
    "backrightleg": "right_back_leg",
    "backrightlegaux": "aux_4",
    "backrightlegankle": "aux_4/child",
}

_HUMANOID_PARTS = {
    "torso": "torso",
    "lwaist": "lwaist",
    "pelvis": "pelvis",
    "rightthigh": "right_thigh",
    "rightshin": "right_shin",
    "rightfoot": "right_foot",
    "leftthigh": "left_thigh",
    "leftshin": "left_shin",
    "leftfoot": "left_foot",
    "rightupperarm": "right_upper_arm",
    "rightlowerarm": "right_lower_arm",
    "leftupperarm": "left_upper_arm",
    "leftlowerarm": "left_lower_arm",
}
# The original code names the lower-waist forces "lwaisforce_*" (sic); keep it for compatibility.
_HUMANOID_FORCE_PARTS = {("lwais" if k == "lwaist" else k): v for k, v in _HUMANOID_PARTS.items()}

TASKS: dict[str, TaskSpec] = {
    t.key: t
    for t in (
        _task(
            "ant",
            "Ant",
            "AntEnv",
            planar=False,
            friction=False,
            parts=_ANT_PARTS,
            sets={
                "1d": {"torsomass": (0.1, 3.0)},
                "2d": {"torsomass": (0.1, 3.0), "frontleftlegmass": (0.01, 3.0)},
                "3d": {
                    "torsomass": (0.1, 3.0),
                    "frontleftlegmass": (0.01, 3.0),
                    "frontrightlegmass": (0.01, 3.0),
                },
                "rarl": _rarl(
                    "torsoforce_x",
                    "torsoforce_y",
                    "frontleftlegforce_x",
                    "frontleftlegforce_y",
                    "frontrightlegforce_x",
                    "frontrightlegforce_y",
                ),
            },
        ),
        _task(
            "halfcheetah",
            "HalfCheetah",
            "HalfCheetahEnv",
            planar=True,
            friction=True,
            parts={
                "torso": "torso",
                "backthigh": "bthigh",
                "backshin": "bshin",
                "backfoot": "bfoot",
                "forwardthigh": "fthigh",
                "forwardshin": "fshin",
                "forwardfoot": "ffoot",
            },
            sets={
                "1d": {"worldfriction": (0.1, 3.0)},
                "2d": {"worldfriction": (0.1, 4.0), "torsomass": (0.1, 7.0)},
                "3d": {
                    "worldfriction": (0.1, 4.0),
                    "torsomass": (0.1, 7.0),
                    "backthighmass": (0.1, 3.0),
                },
                "rarl": _rarl(
                    "torsoforce_x",
                    "torsoforce_y",
                    "backfootforce_x",
                    "backfootforce_y",
                    "forwardfootforce_x",
                    "forwardfootforce_y",
                ),
            },
        ),
        _task(
            "hopper",
            "Hopper",
            "HopperEnv",
            planar=True,
            friction=True,
            parts={"torso": "torso", "thigh": "thigh", "leg": "leg", "foot": "foot"},
            sets={
                "1d": {"worldfriction": (0.1, 3.0)},
                "2d": {"worldfriction": (0.1, 3.0), "torsomass": (0.1, 3.0)},
                "3d": {
                    "worldfriction": (0.1, 3.0),
                    "torsomass": (0.1, 3.0),
                    "thighmass": (0.1, 4.0),
                },
                "rarl": _rarl("footforce_x", "footforce_y"),
            },
        ),
        _task(
            "humanoidstandup",
            "HumanoidStandUp",
            "HumanoidStandupEnv",
            planar=False,
            friction=False,
            parts=_HUMANOID_PARTS,
            force_parts=_HUMANOID_FORCE_PARTS,
            sets={
                "1d": {"torsomass": (0.1, 16.0)},
                "2d": {"torsomass": (0.1, 16.0), "rightfootmass": (0.1, 8.0)},
                # The paper's bounds; the original code swaps the last two (docs/differences.md).
                "3d": {
                    "torsomass": (0.1, 16.0),
                    "rightfootmass": (0.1, 5.0),
                    "leftthighmass": (0.1, 8.0),
                },
                "rarl": _rarl(
                    "torsoforce_x",
                    "torsoforce_y",
                    "rightthighforce_x",
                    "rightthighforce_y",
                    "leftfootforce_x",
                    "leftfootforce_y",
                ),
            },
        ),
        _task(
            "invertedpendulum",
            "InvertedPendulum",
            "InvertedPendulumEnv",
            planar=True,
            friction=False,
            parts={"pole": "pole", "cart": "cart"},
            sets={
                "1d": {"polemass": (1.0, 31.0)},
                "2d": {"polemass": (1.0, 31.0), "cartmass": (1.0, 11.0)},
                "rarl": _rarl("poleforce_x", "poleforce_y"),
            },
        ),
        _task(
            "walker",
            "Walker2d",
            "Walker2dEnv",
            planar=True,
            friction=True,
            parts={
                "torso": "torso",
                "thigh": "thigh",
                "leg": "leg",
                "foot": "foot",
                "leftthigh": "thigh_left",
                "leftleg": "leg_left",
                "leftfoot": "foot_left",
            },
            sets={
                "1d": {"worldfriction": (0.1, 4.0)},
                "2d": {"worldfriction": (0.1, 4.0), "torsomass": (0.1, 5.0)},
                "3d": {
                    "worldfriction": (0.1, 4.0),
                    "torsomass": (0.1, 5.0),
                    "thighmass": (0.1, 6.0),
                },
                "rarl": _rarl("legforce_x", "legforce_y", "leftfootforce_x", "leftfootforce_y"),
            },
        ),
    )
}

#: accepted spellings of the task keys (the CLI and ``evaluate`` take any of them)
TASK_ALIASES = {
    "walker2d": "walker",
    "half_cheetah": "halfcheetah",
    "humanoid_standup": "humanoidstandup",
    "inverted_pendulum": "invertedpendulum",
}


def get_task(key: str) -> TaskSpec:
    """The task spec of ``key`` (``"hopper"``, ``"walker"``, ...), with a clear error."""
    k = key.lower().replace("-", "").replace(" ", "")
    k = TASK_ALIASES.get(k, k)
    if k not in TASKS:
        raise ValueError(f"unknown task {key!r}; valid tasks: {', '.join(TASKS)}")
    return TASKS[k]
