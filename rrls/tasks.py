"""The built-in tasks as data: which Gymnasium v5 env, which parameters, which uncertainty sets.

The paper's six (Ant, HalfCheetah, Hopper, HumanoidStandup, InvertedPendulum, Walker2d) keep the
paper's sets exactly; rrls adds five more (Humanoid, Swimmer, InvertedDoublePendulum, Reacher,
Pusher) whose sets are **rrls's own** (in the paper's 1D/2D/3D style), not the paper's.

Declared through the public :func:`rrls.register_task`, exactly as a user declares a task.
Parameter names are the original RRLS code's (``torsomass``, ``frontleftlegauxmass``, ...); each
maps to a body *by name* in Gymnasium's XML (paper Appendix A). Uncertainty sets are the paper's
Table 2 (M2TD3 sets, ``1d``/``2d``/``3d``) and Table 3 (RARL force sets, ``rarl``, bounds +-3).
Nominal values are never written here: they are read from the compiled model.
"""

from __future__ import annotations

from rrls.params import (
    ALL_GEOMS,
    VISCOSITY,
    Parameter,
    force_params,
    mass_params,
    physics_params,
)
from rrls.registry import (
    BUILTIN_TASKS,
    TASK_ALIASES,
    TASKS,
    Bounds,
    TaskSpec,
    get_task,
    register_task,
)

WORLD_FRICTION = Parameter("worldfriction", "geom_friction", ALL_GEOMS)


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
    joints: dict[str, str],
    actuators: dict[str, str] | None = None,
    force_parts: dict[str, str] | None = None,
    aliases: tuple[str, ...] = (),
    max_episode_steps: int | None = 1000,
    contacts: bool = True,
    extra: tuple[Parameter, ...] = (),
    com: dict[str, str] | None = None,
    paper: bool = False,
) -> TaskSpec:
    """One built-in task: the original code's rows first (``worldfriction``, the masses), then
    every further kind on the same parts (per-body friction, centre-of-mass offsets), on the
    ``joints`` (damping, armature, dry friction), on the ``actuators`` (gear, default: one per
    joint) and on the model (gravity, timestep). ``contacts=False``: a model whose bodies touch
    nothing (no per-body friction rows)."""
    params = (
        ((WORLD_FRICTION,) if friction else ())
        + mass_params(parts)
        + physics_params(parts, joints, actuators, planar, friction=contacts, com=com)
        + extra
    )
    # the built-in tables are checked against the compiled models by the tests, not at import
    # (``import rrls`` builds no model)
    BUILTIN_TASKS.add(key)
    return register_task(
        key,
        f"{cls.removesuffix('Env')}-v5",
        name=name,
        planar=planar,
        params=params,
        forces=force_params(force_parts or parts, planar),
        sets=sets,
        aliases=aliases,
        max_episode_steps=max_episode_steps,
        # the paper's experiments ran the original code after SuReLI/RRLS@68beb84
        # (2023-11-28), which builds every env with gym.make("<Task>-v5") (docs/differences.md)
        paper_env=f"{cls.removesuffix('Env')}-v5" if paper else None,
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
#: Humanoid(Standup)'s hinge joints (each driven by one motor of the same name)
_HUMANOID_JOINTS = {
    j.replace("_", ""): j
    for j in (
        "abdomen_z",
        "abdomen_y",
        "abdomen_x",
        "right_hip_x",
        "right_hip_z",
        "right_hip_y",
        "right_knee",
        "left_hip_x",
        "left_hip_z",
        "left_hip_y",
        "left_knee",
        "right_shoulder1",
        "right_shoulder2",
        "right_elbow",
        "left_shoulder1",
        "left_shoulder2",
        "left_elbow",
    )
}
# The original code names the lower-waist forces "lwaisforce_*" (sic); keep it for compatibility.
_HUMANOID_FORCE_PARTS = {("lwais" if k == "lwaist" else k): v for k, v in _HUMANOID_PARTS.items()}

_task(
    "ant",
    "Ant",
    "AntEnv",
    paper=True,  # paper=True: the original code's env and writes
    planar=False,
    friction=False,
    parts=_ANT_PARTS,
    joints={f"{kind}{i}": f"{kind}_{i}" for i in range(1, 5) for kind in ("hip", "ankle")},
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
    paper=True,  # paper=True: the original code's env and writes
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
    joints={
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
    paper=True,  # paper=True: the original code's env and writes
    planar=True,
    friction=True,
    parts={"torso": "torso", "thigh": "thigh", "leg": "leg", "foot": "foot"},
    joints={"thigh": "thigh_joint", "leg": "leg_joint", "foot": "foot_joint"},
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
    paper=True,  # paper=True: the original code's env and writes
    planar=False,
    friction=False,
    parts=_HUMANOID_PARTS,
    force_parts=_HUMANOID_FORCE_PARTS,
    joints=_HUMANOID_JOINTS,
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
    paper=True,  # paper=True: the original code's env and writes
    planar=True,
    friction=False,
    parts={"pole": "pole", "cart": "cart"},
    joints={"cart": "slider", "pole": "hinge"},
    actuators={"cart": "slide"},
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
    paper=True,  # paper=True: the original code's env and writes
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
    joints={
        "thigh": "thigh_joint",
        "leg": "leg_joint",
        "foot": "foot_joint",
        "leftthigh": "thigh_left_joint",
        "leftleg": "leg_left_joint",
        "leftfoot": "foot_left_joint",
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

# -- rrls's own tasks: the paper has no sets for them; these are rrls's, in the paper's style ----
_task(
    "humanoid",
    "Humanoid",
    "HumanoidEnv",
    planar=False,
    friction=True,
    parts=_HUMANOID_PARTS,
    joints=_HUMANOID_JOINTS,
    sets={
        "1d": {"torsomass": (1.0, 16.0)},
        "2d": {"torsomass": (1.0, 16.0), "worldfriction": (0.2, 2.0)},
        "3d": {"torsomass": (1.0, 16.0), "worldfriction": (0.2, 2.0), "rightthighmass": (1.0, 9.0)},
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
    "swimmer",
    "Swimmer",
    "SwimmerEnv",
    planar=False,  # it swims in the horizontal x-y plane
    friction=False,
    contacts=False,
    parts={"torso": "torso", "mid": "mid", "back": "back"},
    joints={"mid": "motor1_rot", "back": "motor2_rot"},
    extra=(VISCOSITY,),
    sets={
        "1d": {"torsomass": (10.0, 70.0)},
        "2d": {"torsomass": (10.0, 70.0), "viscosity": (0.0, 0.5)},
        "3d": {"torsomass": (10.0, 70.0), "viscosity": (0.0, 0.5), "backmass": (10.0, 70.0)},
        "rarl": _rarl("torsoforce_x", "torsoforce_y", "backforce_x", "backforce_y"),
    },
)
_task(
    "inverteddoublependulum",
    "InvertedDoublePendulum",
    "InvertedDoublePendulumEnv",
    aliases=("inverted_double_pendulum", "idp"),
    planar=True,
    friction=False,
    contacts=False,
    parts={"cart": "cart", "pole": "pole", "pole2": "pole2"},
    joints={"cart": "slider", "pole": "hinge", "pole2": "hinge2"},
    actuators={"cart": "slide"},
    sets={
        "1d": {"polemass": (1.0, 10.0)},
        "2d": {"polemass": (1.0, 10.0), "pole2mass": (1.0, 10.0)},
        "3d": {"polemass": (1.0, 10.0), "pole2mass": (1.0, 10.0), "cartmass": (2.0, 30.0)},
        "rarl": _rarl("poleforce_x", "pole2force_x"),
    },
)
_task(
    "reacher",
    "Reacher",
    "ReacherEnv",
    planar=False,  # its arm moves in the horizontal x-y plane
    friction=False,
    contacts=False,
    parts={"link0": "body0", "link1": "body1", "fingertip": "fingertip"},
    joints={"link0": "joint0", "link1": "joint1"},
    max_episode_steps=None,  # Reacher-v5's own: 50 steps
    sets={
        "1d": {"link1mass": (0.005, 0.2)},
        "2d": {"link1mass": (0.005, 0.2), "link0mass": (0.005, 0.2)},
        "3d": {"link1mass": (0.005, 0.2), "link0mass": (0.005, 0.2), "link1damping": (0.0, 5.0)},
        "rarl": {n: (-0.1, 0.1) for n in ("fingertipforce_x", "fingertipforce_y")},
    },
)
_task(
    "pusher",
    "Pusher",
    "PusherEnv",
    planar=False,
    friction=True,
    parts={
        "shoulderpan": "r_shoulder_pan_link",
        "shoulderlift": "r_shoulder_lift_link",
        "upperarmroll": "r_upper_arm_roll_link",
        "upperarm": "r_upper_arm_link",
        "elbowflex": "r_elbow_flex_link",
        "forearmroll": "r_forearm_roll_link",
        "forearm": "r_forearm_link",
        "wristflex": "r_wrist_flex_link",
        "wristroll": "r_wrist_roll_link",
        "object": "object",
    },
    joints={
        "shoulderpan": "r_shoulder_pan_joint",
        "shoulderlift": "r_shoulder_lift_joint",
        "upperarmroll": "r_upper_arm_roll_joint",
        "elbowflex": "r_elbow_flex_joint",
        "forearmroll": "r_forearm_roll_joint",
        "wristflex": "r_wrist_flex_joint",
        "wristroll": "r_wrist_roll_joint",
        "objectx": "obj_slidex",
        "objecty": "obj_slidey",
    },
    actuators={
        "shoulderpan": "r_shoulder_pan_joint",
        "shoulderlift": "r_shoulder_lift_joint",
        "upperarmroll": "r_upper_arm_roll_joint",
        "elbowflex": "r_elbow_flex_joint",
        "forearmroll": "r_forearm_roll_joint",
        "wristflex": "r_wrist_flex_joint",
        "wristroll": "r_wrist_roll_joint",
    },
    max_episode_steps=None,  # Pusher-v5's own: 100 steps
    # the object is compiled as a 'simple' body: MuJoCo cannot move its centre of mass
    com={
        "shoulderpan": "r_shoulder_pan_link",
        "shoulderlift": "r_shoulder_lift_link",
        "upperarmroll": "r_upper_arm_roll_link",
        "upperarm": "r_upper_arm_link",
        "elbowflex": "r_elbow_flex_link",
        "forearmroll": "r_forearm_roll_link",
        "forearm": "r_forearm_link",
        "wristflex": "r_wrist_flex_link",
        "wristroll": "r_wrist_roll_link",
    },
    sets={
        "1d": {"forearmmass": (0.2, 3.0)},
        "2d": {"forearmmass": (0.2, 3.0), "upperarmmass": (0.5, 5.0)},
        "3d": {
            "forearmmass": (0.2, 3.0),
            "upperarmmass": (0.5, 5.0),
            "shoulderpandamping": (0.2, 5.0),
        },
        "rarl": {n: (-0.05, 0.05) for n in ("objectforce_x", "objectforce_y")},
    },
)


def benchmark_set(task: str) -> str:
    """The paper's benchmark set of ``task`` (§5: every baseline trains on the 3D set;
    InvertedPendulum, which has no 3D set, on its 2D set): the one rule for a default set, of
    training, of the benchmark and of ``rrls evaluate`` when the policy does not name its own."""
    sets = list(get_task(task).sets)
    # a registered task without the paper's names: its first declared set
    return next((s for s in ("3d", "2d", "1d") if s in sets), sets[0] if sets else "nominal")


__all__ = [
    "TASKS",
    "TASK_ALIASES",
    "TaskSpec",
    "WORLD_FRICTION",
    "benchmark_set",
    "get_task",
    "register_task",
]
