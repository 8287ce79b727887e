"""The twin's warp kernels: Gymnasium v5's observation, reward, termination and reset noise,
one world per thread, and the copy of a world's parameter point into MuJoCo Warp's batched
fields. The formulas' families are :data:`rrls.twin.catalog.TWIN_TASKS`; their numbers come in a
:class:`Formula` struct read from the CPU env."""

from __future__ import annotations

import warp as wp

from rrls.twin.catalog import NO_TERMINATION, PENDULUM, Z_ANGLE, Z_ANGLE_STATE, Z_FINITE


@wp.struct
class Formula:
    pos_start: int
    clip_vel: float
    cfrc: int
    health: int
    forward: int
    normal_qvel: int
    forward_weight: float
    ctrl_weight: float
    healthy_reward: float
    terminate: int
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
    frame_skip: int
    max_steps: int


@wp.kernel
def begin_step(
    action: wp.array2d(dtype=float),
    qpos: wp.array2d(dtype=float),
    ctrl: wp.array2d(dtype=float),
    x_before: wp.array(dtype=float),
):
    """Gymnasium's ``do_simulation``: the action becomes ``ctrl`` (MuJoCo clamps it to the
    actuators' ranges); the x position before the step is kept for the forward velocity."""
    w, j = wp.tid()
    ctrl[w, j] = action[w, j]
    if j == 0:
        x_before[w] = qpos[w, 0]


@wp.kernel
def split_action(joint: wp.array2d(dtype=float), action: wp.array2d(dtype=float)):
    """The protagonist's columns of a joint action (RARL's game on the twin)."""
    w, j = wp.tid()
    action[w, j] = joint[w, j]


@wp.kernel
def adversary_point(
    joint: wp.array2d(dtype=float),
    nu: int,
    low: wp.array(dtype=float),
    span: wp.array(dtype=float),
    only: wp.array(dtype=int),
    values: wp.array2d(dtype=float),
):
    """World ``w``'s point from the adversary's columns of its joint action, as
    ``DynamicAdversarial.params_of`` maps them: ``lo + ((clip(a, -1, 1) + 1) * (hi - lo)) / 2``
    in float32 (``only``: the worlds an adversary plays in)."""
    w, i = wp.tid()
    if only[w] == 0:
        return
    a = wp.clamp(joint[w, nu + i], -1.0, 1.0)
    values[w, i] = low[i] + ((a + 1.0) * span[i]) / 2.0


@wp.kernel
def draw_point(
    mask: wp.array(dtype=int),
    only: wp.array(dtype=int),
    seeds: wp.array(dtype=int),
    episode: wp.array(dtype=int),
    low: wp.array(dtype=float),
    span: wp.array(dtype=float),
    values: wp.array2d(dtype=float),
):
    """A resetting world's point for its next episode, uniform in the box, from the world's own
    stream at that episode (past the draws of ``reset_worlds``'s noise); ``only``: the worlds
    that draw their points."""
    w = wp.tid()
    if mask[w] == 0 or only[w] == 0:
        return
    state = wp.rand_init(seeds[w], episode[w] * 4099 + 2048)
    for i in range(values.shape[1]):
        values[w, i] = low[i] + wp.randf(state) * span[i]


@wp.kernel
def write_point(
    values: wp.array2d(dtype=float),
    only: wp.array(dtype=int),
    slot: wp.array(dtype=int),
    param: wp.array(dtype=int),
    c0: wp.array(dtype=float),
    c1: wp.array(dtype=float),
    field: wp.array2d(dtype=float),
):
    """World ``w``'s entry ``e`` of one field at its point: ``c0 + c1 * value`` of parameter
    ``param[e]`` (``rrls.twin.adversary``); ``only``: the worlds whose points are written."""
    w, e = wp.tid()
    if only[w] == 0:
        return
    field[w, slot[e]] = c0[e] + c1[e] * values[w, param[e]]


@wp.func
def healthy(
    f: Formula, qpos: wp.array2d(dtype=float), qvel: wp.array2d(dtype=float), w: int
) -> int:
    nq = qpos.shape[1]
    nv = qvel.shape[1]
    if f.health == Z_ANGLE or f.health == Z_ANGLE_STATE:
        z = qpos[w, 1]
        angle = qpos[w, 2]
        ok = f.z_low < z and z < f.z_high and f.angle_low < angle and angle < f.angle_high
        if f.health == Z_ANGLE_STATE:  # hopper: state_vector()[2:] inside the open range
            for i in range(2, nq):
                if not (f.state_low < qpos[w, i] and qpos[w, i] < f.state_high):
                    ok = False
            for j in range(nv):
                if not (f.state_low < qvel[w, j] and qvel[w, j] < f.state_high):
                    ok = False
        return int(ok)
    if f.health == Z_FINITE:  # ant: a finite state and z in the closed range
        ok = f.z_low <= qpos[w, 2] and qpos[w, 2] <= f.z_high
        return int(ok) * finite(qpos, qvel, w)
    return 1


@wp.func
def finite(qpos: wp.array2d(dtype=float), qvel: wp.array2d(dtype=float), w: int) -> int:
    """1 if world ``w``'s qpos and qvel are all finite."""
    for i in range(qpos.shape[1]):
        if not wp.isfinite(qpos[w, i]):
            return 0
    for j in range(qvel.shape[1]):
        if not wp.isfinite(qvel[w, j]):
            return 0
    return 1


@wp.kernel
def observe(
    f: Formula,
    qpos: wp.array2d(dtype=float),
    qvel: wp.array2d(dtype=float),
    cfrc_ext: wp.array2d(dtype=wp.spatial_vector),
    mask: wp.array(dtype=int),
    obs: wp.array2d(dtype=float),
):
    """``_get_obs``: qpos from ``pos_start``, qvel (clipped where the task clips it), then the
    clipped contact forces of every body but the world (Ant); worlds with ``mask`` 0 are kept."""
    w = wp.tid()
    if mask[w] == 0:
        return
    nq = qpos.shape[1]
    nv = qvel.shape[1]
    k = int(0)
    for i in range(f.pos_start, nq):
        obs[w, k] = qpos[w, i]
        k += 1
    for j in range(nv):
        v = qvel[w, j]
        if f.clip_vel > 0.0:
            v = wp.clamp(v, -f.clip_vel, f.clip_vel)
        obs[w, k] = v
        k += 1
    if f.cfrc != 0:
        for b in range(1, cfrc_ext.shape[1]):
            c = cfrc_ext[w, b]
            for e in range(6):
                obs[w, k] = wp.clamp(c[e], f.cfrc_low, f.cfrc_high)
                k += 1


@wp.kernel
def finish_step(
    f: Formula,
    qpos: wp.array2d(dtype=float),
    qvel: wp.array2d(dtype=float),
    cfrc_ext: wp.array2d(dtype=wp.spatial_vector),
    action: wp.array2d(dtype=float),
    x_before: wp.array(dtype=float),
    timestep: wp.array(dtype=float),
    steps: wp.array(dtype=int),
    reward: wp.array(dtype=float),
    terminated: wp.array(dtype=int),
    truncated: wp.array(dtype=int),
    done: wp.array(dtype=int),
):
    """``step``'s reward, ``terminated`` and the time limit's ``truncated``, per world."""
    w = wp.tid()
    steps[w] = steps[w] + 1
    ok = healthy(f, qpos, qvel, w)
    term = int(0)
    r = float(0.0)
    if f.health == PENDULUM:
        bad = 1 - finite(qpos, qvel, w)
        if wp.abs(qpos[w, 1]) > 0.2:
            bad = 1
        term = bad
        r = float(1 - bad)
    else:
        dt = timestep[w] * float(f.frame_skip)
        velocity = (qpos[w, 0] - x_before[w]) / dt
        ctrl_cost = float(0.0)
        for j in range(action.shape[1]):
            ctrl_cost += action[w, j] * action[w, j]
        r = f.forward_weight * velocity - f.ctrl_weight * ctrl_cost
        if f.health != NO_TERMINATION:
            r += float(ok) * f.healthy_reward
            if f.terminate != 0 and ok == 0:
                term = 1
        if f.cfrc != 0:
            contact = float(0.0)
            for b in range(cfrc_ext.shape[1]):
                c = cfrc_ext[w, b]
                for e in range(6):
                    x = wp.clamp(c[e], f.cfrc_low, f.cfrc_high)
                    contact += x * x
            r -= f.contact_weight * contact
    reward[w] = r
    terminated[w] = term
    trunc = int(0)
    if term == 0 and steps[w] >= f.max_steps:
        trunc = 1
    truncated[w] = trunc
    done[w] = int(term != 0 or trunc != 0)


@wp.kernel
def reset_worlds(
    f: Formula,
    mask: wp.array(dtype=int),
    seeds: wp.array(dtype=int),
    episode: wp.array(dtype=int),
    qpos0: wp.array(dtype=float),
    pool_size: int,
    redraw: int,
    qpos: wp.array2d(dtype=float),
    qvel: wp.array2d(dtype=float),
    steps: wp.array(dtype=int),
    point: wp.array(dtype=int),
):
    """``reset_model``: the initial state plus noise from the world's own stream (its seed, its
    episode count); with ``redraw`` a new point index drawn uniformly from the pool."""
    w = wp.tid()
    if mask[w] == 0:
        return
    state = wp.rand_init(seeds[w], episode[w] * 4099)
    for i in range(qpos.shape[1]):
        qpos[w, i] = qpos0[i] + wp.randf(state, -f.noise, f.noise)
    for j in range(qvel.shape[1]):
        if f.normal_qvel != 0:
            qvel[w, j] = f.noise * wp.randn(state)
        else:
            qvel[w, j] = wp.randf(state, -f.noise, f.noise)
    if redraw != 0:
        point[w] = wp.min(int(wp.randf(state) * float(pool_size)), pool_size - 1)
    episode[w] = episode[w] + 1
    steps[w] = 0


@wp.kernel
def copy_point(
    mask: wp.array(dtype=int),
    point: wp.array(dtype=int),
    pool: wp.array2d(dtype=float),
    field: wp.array2d(dtype=float),
):
    """Write each reset world's point (one packed field of it) into its batched slot."""
    w, j = wp.tid()
    if mask[w] != 0:
        field[w, j] = pool[point[w], j]


__all__ = [
    "Formula",
    "begin_step",
    "adversary_point",
    "copy_point",
    "draw_point",
    "finish_step",
    "finite",
    "healthy",
    "observe",
    "reset_worlds",
    "split_action",
    "write_point",
]
