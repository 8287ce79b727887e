"""The built-in tasks as data: which Gymnasium v5 env, which parameters, which uncertainty sets.

Declared through the public :func:`rrls.register_task`, exactly as a user declares a task.
Parameter names are the original RRLS code's (``torsomass``, ``frontleftlegauxmass``, ...); each
maps to a body *by name* in Gymnasium's XML (paper Appendix A). Uncertainty sets are the paper's
Table 2 (M2TD3 sets, ``1d``/``2d``/``3d``) and Table 3 (RARL force sets, ``rarl``, bounds +-3).
Nominal values are never written here: they are read from the compiled model.
"""

from __future__ import annotations

from rrls.params import ALL_GEOMS, ParamSpec, force_params, mass_params
from rrls.registry import TASK_ALIASES, TASKS, Bounds, TaskSpec, get_task, register_task

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
    aliases: tuple[str, ...] = (),
) -> TaskSpec:
    params = ((WORLD_FRICTION,) if friction else ()) + mass_params(parts)
    # the built-in tables are checked against the compiled models by the tests, not at import
    # (``import rrls`` builds no model)
    return register_task(
        key,
        f"{cls.removesuffix('Env')}-v5",
        name=name,
        planar=planar,
        params=params,
        forces=force_params(force_parts or parts, planar),
        sets=sets,
        aliases=aliases,
        max_episode_steps=1000,
        check=False,
    )


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
)
_task(
    "halfcheetah",
    "HalfCheetah",
    "HalfCheetahEnv",
    aliases=("half_cheetah",),
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
)
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
)
_task(
    "humanoidstandup",
    "HumanoidStandUp",
    "HumanoidStandupEnv",
    aliases=("humanoid_standup",),
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
)
_task(
    "invertedpendulum",
    "InvertedPendulum",
    "InvertedPendulumEnv",
    aliases=("inverted_pendulum",),
    planar=True,
    friction=False,
    parts={"pole": "pole", "cart": "cart"},
    sets={
        "1d": {"polemass": (1.0, 31.0)},
        "2d": {"polemass": (1.0, 31.0), "cartmass": (1.0, 11.0)},
        "rarl": _rarl("poleforce_x", "poleforce_y"),
    },
)
_task(
    "walker",
    "Walker2d",
    "Walker2dEnv",
    aliases=("walker2d",),
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
)

__all__ = ["TASKS", "TASK_ALIASES", "TaskSpec", "WORLD_FRICTION", "get_task", "register_task"]
