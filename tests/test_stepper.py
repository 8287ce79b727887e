"""The threaded physics of the lockstep lanes: the same numbers as one thread, bit for bit."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

from rrls.envs import FORCE_ENVS, ROBUST_ENVS
from rrls.evaluation import MLPPolicy, engine, resolve_uncertainty
from rrls.evaluation.kernels import FastStepper, GenericStepper, LaneSteps, make_stepper
from rrls.evaluation.lanes import Rollouts, episode_seeds

LANES = 7  # not a multiple of the thread counts: uneven shares


def _envs(task: str) -> list:
    """Lanes with different parameter values (each its own MjModel), reset with their seeds."""
    cls = ROBUST_ENVS[task]
    nominal = cls().get_params()
    name = next(iter(nominal))
    envs = []
    for lane in range(LANES):
        env = cls()
        env.set_params(**{name: nominal[name] * (0.6 + 0.15 * lane)})
        env.reset(seed=lane)
        envs.append(env)
    return envs


@pytest.mark.parametrize("threads", [2, 3, 8])
def test_threads_step_every_lane_exactly_as_one_thread(threads):
    """State, solver warm start and time after many steps of a changing subset of lanes."""
    one, many = _envs("halfcheetah"), _envs("halfcheetah")
    nstep = one[0].frame_skip
    seq = LaneSteps([e.model for e in one], [e.data for e in one], nstep)
    par = LaneSteps([e.model for e in many], [e.data for e in many], nstep, threads)
    rng = np.random.default_rng(0)
    for _ in range(60):
        lanes = sorted(rng.choice(LANES, size=rng.integers(1, LANES + 1), replace=False).tolist())
        actions = rng.uniform(-1, 1, (len(lanes), one[0].action_space.shape[0]))
        seq(lanes, actions)
        par(lanes, actions)
    par.close()
    for a, b in zip(one, many):
        for field in ("qpos", "qvel", "act", "qacc_warmstart", "ctrl", "time"):
            np.testing.assert_array_equal(getattr(a.data, field), getattr(b.data, field), field)
    assert any(a.data.time != one[0].data.time for a in one)  # the subsets differed


@pytest.mark.parametrize("task", ["hopper", "walker", "halfcheetah", "invertedpendulum"])
def test_threaded_fast_stepper_equals_each_env_step(task):
    fast_envs, generic_envs = _envs(task), _envs(task)
    fast = make_stepper(fast_envs, task, threads=3)
    assert type(fast) is FastStepper and fast.physics.shares.threads == 3
    generic = GenericStepper(generic_envs)
    for lane in range(LANES):
        fast.reset(lane, fast_envs[lane].unwrapped._get_obs())
    _assert_lockstep_equal(fast, generic, fast_envs[0].action_space, steps=80, seed=1)
    fast.close()


@pytest.mark.parametrize("task", ["ant", "hopper"])
def test_threaded_generic_stepper_equals_one_thread(task):
    """Bare envs' own ``step`` on threads (Ant: the generic path's task)."""
    one, many = _envs(task), _envs(task)
    seq, par = GenericStepper(one), GenericStepper(many, threads=3)
    assert par.shares.threads == 3
    _assert_lockstep_equal(par, seq, one[0].action_space, steps=40, seed=2)
    par.close()


def test_wrapped_envs_step_on_one_thread():
    """Wrappers of different lanes may share objects (a schedule): never stepped at once."""
    envs = [gym.wrappers.ClipAction(ROBUST_ENVS["ant"]()) for _ in range(3)]
    assert GenericStepper(envs, threads=3).shares.threads == 1


@pytest.mark.filterwarnings("ignore:MuJoCo. Nan, Inf or huge value")  # the point of it
def test_divergence_in_a_pool_thread_is_flagged():
    """MuJoCo's instability warning, raised while a pool thread steps, reaches the lane's row."""
    envs = [FORCE_ENVS["hopper"]() for _ in range(4)]
    for lane, env in enumerate(envs):
        env.set_params(torsoforce_x=1e12 if lane == 3 else 0.0)
        env.reset(seed=lane)
    fast = make_stepper(envs, "hopper", threads=4)
    assert type(fast) is FastStepper
    for lane in range(4):
        fast.reset(lane, envs[lane].unwrapped._get_obs())
    every = np.arange(4)
    diverged = np.zeros(4, dtype=bool)
    for _ in range(20):
        diverged |= fast.step(every, np.zeros((4, 3)))[3]
    fast.close()
    assert diverged.tolist() == [False, False, False, True]


def test_engine_rows_do_not_depend_on_threads():
    task = "hopper"
    box = resolve_uncertainty(task, "3d")
    points = box.mesh(2)
    spec = Rollouts(task, "robust", box.names, points, episode_seeds(0, len(points), 2), 200)
    env = ROBUST_ENVS[task]()
    policy = MLPPolicy.random(
        env.observation_space.shape[0], env.action_space.shape[0], hidden=(16,), seed=0
    )
    one = engine.run(spec, policy, workers=1, lanes=5, threads=1, progress=False)
    three = engine.run(spec, policy, workers=1, lanes=5, threads=3, progress=False)
    for col in one:
        np.testing.assert_array_equal(one[col], three[col], err_msg=col)
    assert one["length"].min() < one["length"].max()  # lanes ended at different steps


def test_bad_thread_count_is_refused():
    env = ROBUST_ENVS["hopper"]()
    for bad in (0, 1.5):
        with pytest.raises(ValueError, match=f"threads must be an integer >= 1, got {bad}"):
            LaneSteps([env.model], [env.data], 4, threads=bad)


def _assert_lockstep_equal(got_stepper, want_stepper, space, steps: int, seed: int) -> None:
    """Both steppers given the same random actions on their live lanes return the same
    observations, rewards and flags, step by step, until every lane's episode has ended."""
    rng = np.random.default_rng(seed)
    alive = np.ones(LANES, dtype=bool)
    for step in range(steps):
        live = np.flatnonzero(alive)
        actions = rng.uniform(space.low, space.high, (len(live), space.shape[0]))
        got, want = got_stepper.step(live, actions), want_stepper.step(live, actions)
        for what, g, w in zip(("obs", "reward", "terminated", "diverged"), got, want):
            np.testing.assert_array_equal(g, w, err_msg=f"{what} differs at step {step}")
        alive[live[want[2] | want[3]]] = False
        if not alive.any():
            break
