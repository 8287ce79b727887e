"""Which tasks have a MuJoCo Warp twin, and the formulas of their Gymnasium v5 step, as data.

A row names the *formula family* of the task's observation, reward and termination; the numbers
in them (reward weights, healthy ranges, reset noise) are read from the CPU env the twin is built
beside, so keyword arguments given to that env hold on the twin too. Each family is Gymnasium
v5's code (``gymnasium/envs/mujoco/<task>_v5.py``: ``_get_obs``, ``_get_rew``, ``is_healthy``,
``reset_model``), written once as a warp kernel in :mod:`rrls.twin.warp_kernels`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

#: families of :class:`TwinTask.health`
NO_TERMINATION, Z_ANGLE, Z_ANGLE_STATE, Z_FINITE, PENDULUM = 0, 1, 2, 3, 4


@dataclass(frozen=True)
class TwinTask:
    """One task's v5 formulas. ``pos_start``: the first qpos entry the observation keeps (the
    excluded x, or x and y); ``clip_vel``: the observation's velocity clip (0: none); ``cfrc``:
    the clipped external contact forces of every body but the world appended (Ant);
    ``health``: the termination family; ``normal_qvel``: reset velocity noise ``scale * N(0, 1)``
    instead of ``U(-scale, scale)``; ``forward``: a forward-velocity reward (else 1 per healthy
    step)."""

    key: str
    pos_start: int
    clip_vel: float
    health: int
    normal_qvel: bool
    forward: bool = True
    cfrc: bool = False


TWIN_TASKS: dict[str, TwinTask] = {
    t.key: t
    for t in (
        TwinTask("hopper", 1, 10.0, Z_ANGLE_STATE, normal_qvel=False),
        TwinTask("walker", 1, 10.0, Z_ANGLE, normal_qvel=False),
        TwinTask("halfcheetah", 1, 0.0, NO_TERMINATION, normal_qvel=True),
        TwinTask("ant", 2, 0.0, Z_FINITE, normal_qvel=True, cfrc=True),
        TwinTask("invertedpendulum", 0, 0.0, PENDULUM, normal_qvel=False, forward=False),
    )
}

#: tasks whose XML MuJoCo Warp cannot run, and why (one line each)
REFUSED: dict[str, str] = {
    "humanoidstandup": "its XML uses the PGS solver, which MuJoCo Warp does not implement "
    "(it supports Newton and CG, which stay within the twin's tolerance of PGS here, but the "
    "twin has no kernels yet for HumanoidStandup's observation and reward)",
}

#: where a twin is known to part from CPU MuJoCo faster than float32 rounding explains
DIVERGES: dict[str, str] = {
    "ant": "MuJoCo Warp and CPU MuJoCo part at the feet's first contacts (the ant lands within "
    "3 env steps of a reset): ~1e-3 in qpos after one contact on Gymnasium's own Ant-v5, with "
    "RK4 or Euler; 0.1-0.4 after 10 env steps",
}

#: rrls parameter fields the twin carries per world (``opt_viscosity``: MuJoCo Warp applies
#: per-world viscosity only to models built with fluid forces on, which these are not)
UNSUPPORTED_FIELDS: dict[str, str] = {
    "opt_viscosity": "MuJoCo Warp ignores a per-world viscosity unless the model was built "
    "with fluid forces on (these tasks' XML is not)",
}


@dataclass(frozen=True)
class Constants:
    """The numbers in a family's formulas, read from the CPU env."""

    forward_weight: float
    ctrl_weight: float
    healthy_reward: float
    terminate: bool
    z_low: float
    z_high: float
    angle_low: float
    angle_high: float
    state_low: float
    state_high: float
    contact_weight: float
    cfrc_low: float
    cfrc_high: float
    noise: float


def fill_formula(f: Any, env: Any, task: TwinTask, max_steps: int) -> Any:
    """The twin kernels' ``Formula`` struct ``f`` filled for ``task``: its flags, the numbers of
    its CPU env ``env`` (``constants``), its frame skip and episode limit."""
    c = constants(env, task)
    f.pos_start, f.clip_vel, f.health = task.pos_start, task.clip_vel, task.health
    f.cfrc, f.forward, f.normal_qvel = int(task.cfrc), int(task.forward), int(task.normal_qvel)
    for name in FORMULA_NUMBERS:
        setattr(f, name, getattr(c, name))
    f.terminate, f.frame_skip, f.max_steps = int(c.terminate), int(env.frame_skip), int(max_steps)
    return f


#: the ``Constants`` a twin kernel reads, by name
FORMULA_NUMBERS = (
    "forward_weight",
    "ctrl_weight",
    "healthy_reward",
    "z_low",
    "z_high",
    "angle_low",
    "angle_high",
    "state_low",
    "state_high",
    "contact_weight",
    "cfrc_low",
    "cfrc_high",
    "noise",
)


def constants(env: Any, task: TwinTask) -> Constants:
    """Read the formulas' numbers from a Gymnasium v5 env (its constructor's keyword arguments)."""

    def get(name: str, default: Any) -> Any:
        return getattr(env, name, default)

    z = get("_healthy_z_range", (-float("inf"), float("inf")))
    angle = get("_healthy_angle_range", (-float("inf"), float("inf")))
    state = get("_healthy_state_range", (-float("inf"), float("inf")))
    cfrc = get("_contact_force_range", (-1.0, 1.0))
    return Constants(
        forward_weight=float(get("_forward_reward_weight", 1.0)),
        ctrl_weight=float(get("_ctrl_cost_weight", 0.0)),
        healthy_reward=float(get("_healthy_reward", 0.0)),
        terminate=bool(get("_terminate_when_unhealthy", task.health != NO_TERMINATION)),
        z_low=float(z[0]),
        z_high=float(z[1]),
        angle_low=float(angle[0]),
        angle_high=float(angle[1]),
        state_low=float(state[0]),
        state_high=float(state[1]),
        contact_weight=float(get("_contact_cost_weight", 0.0)),
        cfrc_low=float(cfrc[0]),
        cfrc_high=float(cfrc[1]),
        noise=float(get("_reset_noise_scale", 0.0)),
    )


def not_on_twin(algo: str) -> str | None:
    """Why no twin path trains ``algo``, or None: every built-in algorithm has one now. An
    adversary mixing into the action (NR-MDP) trains device-resident, its learner returning the
    executed action; one moving the dynamics (RARL) too, on a twin built with ``adversary=True``
    (``rrls.agents.resident.make_twin``), its point written into each world inside the step.
    Kept as the one place a future refusal of a whole algorithm would go."""
    return None


def check_twin(algo: str, task: str, physics: str) -> None:
    """Refuse, in one line saying why, a run the Warp twin cannot train."""
    from rrls.physics import is_paper

    why = not_on_twin(algo)
    if why is not None:
        raise ValueError(f"--simulator warp: {algo} does not train on the twin: {why}")
    if task in REFUSED:
        raise ValueError(f"--simulator warp: no twin for {task!r}: {REFUSED[task]}")
    if task not in TWIN_TASKS:
        raise ValueError(
            f"--simulator warp: no twin for {task!r}; tasks with one: {', '.join(TWIN_TASKS)}"
        )
    if is_paper(physics):
        raise ValueError(
            "--simulator warp trains on rrls's v5 physics; --physics paper is CPU only"
        )
    import importlib.util

    missing = [m for m in ("warp", "mujoco_warp") if importlib.util.find_spec(m) is None]
    if missing:
        from rrls.extras import install_hint

        raise ValueError(f"--simulator warp needs {', '.join(missing)}: {install_hint('warp')}")


__all__ = [
    "not_on_twin",
    "check_twin",
    "DIVERGES",
    "FORMULA_NUMBERS",
    "NO_TERMINATION",
    "PENDULUM",
    "REFUSED",
    "TWIN_TASKS",
    "UNSUPPORTED_FIELDS",
    "Z_ANGLE",
    "Z_ANGLE_STATE",
    "Z_FINITE",
    "Constants",
    "TwinTask",
    "constants",
    "fill_formula",
]
