"""Stepping many environments of one task in lockstep.

``GenericStepper`` calls each env's own ``step``: exact for any env, and enough where the physics
dominates (Ant, HumanoidStandup). For the planar tasks Gymnasium's Python around ``mj_step``
(observation, health checks, reward, info dict) costs 25-40 % of a step, so ``FastStepper`` runs the
same MuJoCo calls per lane and then computes observations, rewards and terminations for all lanes
at once with numpy, with the *same operations in the same order and dtypes* as Gymnasium v5's
``step`` — the equivalence tests compare both paths bit for bit, task by task. Every parameter
kind lives in the ``MjModel`` that ``mj_step`` reads, so the fast path is exact for all of them;
the one Python-side constant, ``dt`` (``frame_skip * opt.timestep``, a parameter), is read per
lane at each reset.

Both report a lane as diverged when MuJoCo flagged the simulation as unstable during the episode
(``mjWARN_BADQPOS``/``BADQVEL``/``BADQACC``: MuJoCo then resets the data and carries on, so the
rest of the episode would be meaningless) or the observation or reward is not finite.

Both can step lanes on several threads (``Shares``): ``mujoco.mj_step`` releases the GIL, and
each lane steps its own ``MjData``, so K threads step K lanes at once with the very same calls
(``FastStepper``: its ``mj_step`` calls, ``LaneSteps``; ``GenericStepper``: bare envs' ``step``).
``mujoco.rollout`` would step all lanes in one C call, but it goes through state vectors on one
``MjData`` per *thread*: each lane's ``qacc_warmstart`` (the solver's starting point, so its
result) and warning counters would not survive from one step to the next.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor, wait
from typing import Any

import mujoco
import numpy as np


class Shares:
    """Runs ``work(first, k)`` for the ``k`` interleaved shares of ``n`` items (``first``,
    ``first + k``, ...): one on the calling thread, the others on ``threads - 1`` pool threads.

    Interleaved, so lanes with costly contacts spread out. It pays only for work that releases the
    GIL (``mj_step`` does): the Python around it still takes turns, so threads pay where a process
    has cores to itself (fewer worker processes than cores, or one process stepping many runs'
    envs), not where every core already runs a worker. There, they cannot: a worker spends only
    2-4 % of its CPU time in the Python around ``mj_step`` (the policy 17-27 %, ``mj_step`` 60-75 %
    on Hopper and HalfCheetah: ``benchmarks/evaluation.py --threads``).
    """

    def __init__(self, threads: int = 1) -> None:
        if int(threads) != threads or threads < 1:
            raise ValueError(f"threads must be an integer >= 1, got {threads!r}")
        self.threads = int(threads)
        self._pool = ThreadPoolExecutor(self.threads - 1) if self.threads > 1 else None

    def __call__(self, work: Callable[[int, int], None], n: int) -> None:
        k = min(self.threads, n)
        if self._pool is None or k < 2:
            work(0, 1)
            return
        others = [self._pool.submit(work, first, k) for first in range(1, k)]
        try:
            work(0, k)
        finally:
            wait(others)  # the shares write into the caller's arrays: none outlives the call
        for share in others:
            share.result()  # re-raises an error (a MuJoCo error) from a pool thread

    def close(self) -> None:
        """Stop the pool threads (later calls run on the calling thread)."""
        if self._pool is not None:
            self._pool.shutdown()
            self._pool = None
            self.threads = 1


class LaneSteps:
    """``ctrl = action; mj_step(model, data, nstep)`` for many lanes, on ``threads`` threads.

    Each lane steps its own ``MjData`` (no state copies), so the numbers are those of one thread.
    """

    def __init__(
        self, models: Sequence[Any], datas: Sequence[Any], nstep: int, threads: int = 1
    ) -> None:
        self.models, self.datas, self.nstep = list(models), list(datas), nstep
        self.ctrls = [d.ctrl for d in self.datas]  # MjData buffers never move: views taken once
        self.shares = Shares(threads)

    def __call__(self, lanes: list[int], actions: np.ndarray) -> None:
        """Apply ``actions[j]`` to lane ``lanes[j]`` and step it ``nstep`` times."""
        models, datas, ctrls, nstep = self.models, self.datas, self.ctrls, self.nstep
        mj_step = mujoco.mj_step

        def work(first: int, k: int) -> None:
            for j in range(first, len(lanes), k):
                lane = lanes[j]
                ctrls[lane][:] = actions[j]
                mj_step(models[lane], datas[lane], nstep=nstep)

        self.shares(work, len(lanes))

    def close(self) -> None:
        self.shares.close()


class GenericStepper:
    """Steps each lane through its env's own ``step`` (wrappers included: disruptors, schedules).

    ``threads`` > 1 steps bare envs on that many threads (each env's ``step`` touches only its
    own env; Gymnasium's ``mj_step`` releases the GIL); wrapped envs step on the calling thread,
    as wrappers of different lanes may share objects (a schedule).
    """

    def __init__(self, envs: Sequence[Any], threads: int = 1) -> None:
        self.envs = list(envs)
        # the stat objects stay bound to each MjData; mj_resetData zeroes them at every reset
        bad = (
            mujoco.mjtWarning.mjWARN_BADQPOS,
            mujoco.mjtWarning.mjWARN_BADQVEL,
            mujoco.mjtWarning.mjWARN_BADQACC,
        )
        self._warnings = [[e.unwrapped.data.warning[w] for w in bad] for e in self.envs]
        bare = all(e is e.unwrapped for e in self.envs)
        self.shares = Shares(threads if bare else 1)
        self.obs_dim = self.envs[0].observation_space.shape[0] if self.envs else 0

    def unstable(self, lanes: list[int]) -> np.ndarray:
        """Lanes whose simulation MuJoCo found unstable since their last reset."""
        stats = [self._warnings[lane] for lane in lanes]
        return np.array([bool(p.number or v.number or a.number) for p, v, a in stats], dtype=bool)

    def reset(self, lane: int, obs: np.ndarray) -> None:
        """Called after ``envs[lane].reset(...)``; ``obs`` is its first observation."""

    def close(self) -> None:
        """Stop the stepping threads; the envs stay open."""
        self.shares.close()

    def step(
        self, lanes: np.ndarray, actions: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        n, envs, idx = len(lanes), self.envs, lanes.tolist()
        obs = np.empty((n, self.obs_dim))
        rewards = np.empty(n)
        terminated = np.zeros(n, dtype=bool)

        def work(first: int, k: int) -> None:
            for j in range(first, n, k):
                obs[j], rewards[j], terminated[j], _, _ = envs[idx[j]].step(actions[j])

        self.shares(work, n)
        diverged = self.unstable(idx)
        diverged |= ~np.isfinite(rewards) | ~np.isfinite(obs).all(axis=1)
        return obs, rewards, terminated, diverged


class FastStepper(GenericStepper):
    """Vectorised Gymnasium v5 step for Hopper, Walker2d, HalfCheetah and InvertedPendulum."""

    TASKS = ("hopper", "walker", "halfcheetah", "invertedpendulum")

    def __init__(self, envs: Sequence[Any], task: str, threads: int = 1) -> None:
        super().__init__(envs)  # one thread for env.step: FastStepper never calls it
        if task not in self.TASKS:
            raise ValueError(f"no fast stepper for {task!r}; valid: {', '.join(self.TASKS)}")
        self.task = task
        env = self.envs[0]
        datas = [e.data for e in self.envs]
        self.physics = LaneSteps([e.model for e in self.envs], datas, env.frame_skip, threads)
        # MjData buffers never move: take the numpy views once instead of at every step
        self.qposs = [d.qpos for d in datas]
        self.qvels = [d.qvel for d in datas]
        # per lane: the timestep is a parameter (Gymnasium's dt = frame_skip * opt.timestep)
        self.dts = np.array([e.dt for e in self.envs])
        self.x_before = np.zeros(len(self.envs))
        if task != "invertedpendulum":
            self.w_forward = env._forward_reward_weight
            self.w_ctrl = env._ctrl_cost_weight
            self.exclude_x = env._exclude_current_positions_from_observation
        if task in ("hopper", "walker"):
            self.w_healthy = env._healthy_reward
            self.terminate_when_unhealthy = env._terminate_when_unhealthy
            self.z_range = env._healthy_z_range
            self.angle_range = env._healthy_angle_range
            self.state_range = getattr(env, "_healthy_state_range", None)

    def reset(self, lane: int, obs: np.ndarray) -> None:
        self.x_before[lane] = self.qposs[lane][0]
        self.dts[lane] = self.envs[lane].dt

    def close(self) -> None:
        super().close()
        self.physics.close()

    def step(
        self, lanes: np.ndarray, actions: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        idx = lanes.tolist()
        # Gymnasium also calls mj_rnePostConstraint after mj_step; it only fills cacc/cfrc_*
        # (used by none of these four tasks' observations or rewards, nor by the next mj_step).
        self.physics(idx, actions)
        diverged = self.unstable(idx)
        qpos = np.array([self.qposs[lane] for lane in idx])
        qvel = np.array([self.qvels[lane] for lane in idx])

        if self.task == "invertedpendulum":
            obs = np.concatenate([qpos, qvel], axis=1)
            finite = np.isfinite(obs).all(axis=1)
            terminated = ~finite | (np.abs(obs[:, 1]) > 0.2)
            rewards = (~terminated).astype(np.int64)  # Gymnasium: int(not terminated)
            return obs, rewards, terminated, diverged | ~finite

        x_after = qpos[:, 0]
        x_velocity = (x_after - self.x_before[lanes]) / self.dts[lanes]
        self.x_before[lanes] = x_after
        position = qpos[:, 1:] if self.exclude_x else qpos
        velocity = qvel if self.task == "halfcheetah" else np.clip(qvel, -10, 10)
        obs = np.concatenate((position, velocity), axis=1)
        forward_reward = self.w_forward * x_velocity
        ctrl_cost = self.w_ctrl * np.sum(np.square(actions), axis=1)
        if self.task == "halfcheetah":
            rewards = forward_reward - ctrl_cost
            terminated = np.zeros(len(lanes), dtype=bool)
        else:
            healthy = self._is_healthy(qpos, qvel)
            rewards = (forward_reward + healthy * self.w_healthy) - ctrl_cost
            terminated = ~healthy & bool(self.terminate_when_unhealthy)
        diverged |= ~np.isfinite(rewards) | ~np.isfinite(obs).all(axis=1)
        return obs, rewards, terminated, diverged

    def _is_healthy(self, qpos: np.ndarray, qvel: np.ndarray) -> np.ndarray:
        z, angle = qpos[:, 1], qpos[:, 2]
        (min_z, max_z), (min_a, max_a) = self.z_range, self.angle_range
        healthy = (min_z < z) & (z < max_z) & (min_a < angle) & (angle < max_a)
        if self.task == "hopper":
            state = np.concatenate((qpos, qvel), axis=1)[:, 2:]
            min_s, max_s = self.state_range
            healthy &= np.all((min_s < state) & (state < max_s), axis=1)
        return healthy


def fast_stepper_applies(envs: Sequence[Any], task: str) -> bool:
    """Whether :class:`FastStepper` reproduces ``env.step`` for these envs.

    Only for the exact default ``Robust<Task>``/``Force<Task>`` classes of the four planar tasks,
    built with no Gymnasium keyword (physical parameters only): a subclass may override ``step``
    and a keyword (reward weights, XML file, health ranges) may change what it computes.
    """
    from rrls.envs import FAMILY_ENVS

    if task not in FastStepper.TASKS or not envs:
        return False
    defaults = {FAMILY_ENVS[family][task] for family in FAMILY_ENVS}
    for env in envs:
        cls = type(env)
        if cls not in defaults:
            return False
        kwargs = getattr(env, "_ezpickle_kwargs", None)
        if kwargs is None or set(kwargs) - {"scale_inertia", *cls._names()}:
            return False
    return True


def make_stepper(
    envs: Sequence[Any], task: str, fast: bool = True, threads: int = 1
) -> GenericStepper:
    """The fastest exact stepper for ``task``'s envs (the generic one unless it provably fits);
    ``threads``: how many threads step the lanes (the physics of the fast one, the whole ``step``
    of bare envs in the generic one)."""
    if fast and fast_stepper_applies(envs, task):
        return FastStepper(envs, task, threads)
    return GenericStepper(envs, threads)


__all__ = [
    "FastStepper",
    "GenericStepper",
    "LaneSteps",
    "Shares",
    "fast_stepper_applies",
    "make_stepper",
]
