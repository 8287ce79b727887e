"""Disruptors: each effect reaches what it claims, seeds reproduce, strengths are parameters."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import rrls  # noqa: F401
from rrls.envs import RobustHopper
from rrls.wrappers import (
    DISRUPTORS,
    ActionDelay,
    ActionNoise,
    ContextObservation,
    DomainRandomization,
    DynamicAdversarial,
    ObservationDelay,
    ObservationDropout,
    ObservationNoise,
    RewardNoise,
    StuckSensors,
    disrupt,
)

ACTIONS = np.random.default_rng(5).uniform(-1, 1, (40, 3))


def run(env, seed=0, actions=ACTIONS):
    """Observations, rewards, infos and the true MuJoCo state after each step."""
    obs, _ = env.reset(seed=seed)
    out = {"obs": [obs], "reward": [], "info": [], "qpos": [], "ctrl": []}
    for a in actions:
        obs, r, term, trunc, info = env.step(a)
        out["obs"].append(obs)
        out["reward"].append(r)
        out["info"].append(info)
        out["qpos"].append(env.unwrapped.data.qpos.copy())
        out["ctrl"].append(env.unwrapped.data.ctrl.copy())
        if term or trunc:
            break
    return {k: v if k == "info" else np.array(v) for k, v in out.items()}


def test_all_disruptors_at_zero_change_nothing():
    bare = run(RobustHopper())
    stacked = run(disrupt(RobustHopper(), **{name: 0 for name in DISRUPTORS}))
    for key in ("obs", "reward", "qpos", "ctrl"):
        assert np.array_equal(bare[key], stacked[key]), key


def test_observation_noise_reaches_the_observation_not_the_physics():
    bare = run(RobustHopper())
    noisy = run(ObservationNoise(RobustHopper(), std=0.05))
    assert np.array_equal(bare["qpos"], noisy["qpos"])  # same physics (actions are fixed)
    diff = noisy["obs"] - bare["obs"]
    assert np.all(diff != 0)
    assert 0.04 < diff.std() < 0.06 and abs(diff.mean()) < 0.01


def test_dropout_zeroes_components_with_the_given_probability_and_duration():
    bare = run(RobustHopper())
    dropped = run(ObservationDropout(RobustHopper(), probability=0.3))
    zero = (dropped["obs"] == 0) & (bare["obs"] != 0)
    assert 0.2 < zero.mean() < 0.4
    assert np.array_equal(dropped["obs"][~zero], bare["obs"][~zero])
    assert np.all(run(ObservationDropout(RobustHopper(), probability=1.0))["obs"] == 0)
    held = run(ObservationDropout(RobustHopper(), probability=0.05, duration=4))["obs"] == 0
    lengths = []
    for j in range(held.shape[1]):  # a dropout lasts 4 steps (unless the episode ends)
        edges = np.flatnonzero(np.diff(np.r_[0, held[:, j].astype(int), 0]))
        starts, stops = edges[::2], edges[1::2]
        lengths += [b - a for a, b in zip(starts, stops) if b < len(held)]
    assert lengths and all(n % 4 == 0 for n in lengths)


def test_stuck_sensors_repeat_the_last_reading():
    bare = run(RobustHopper())
    stuck = run(StuckSensors(RobustHopper(), probability=0.3))
    same = stuck["obs"][1:] == stuck["obs"][:-1]
    assert 0.2 < same.mean() < 0.45
    assert np.array_equal(stuck["qpos"], bare["qpos"])
    always = run(StuckSensors(RobustHopper(), probability=1.0))["obs"]
    assert np.all(always == always[0])


def test_observation_delay_shows_the_observation_of_k_steps_ago():
    bare = run(RobustHopper())
    late = run(ObservationDelay(RobustHopper(), steps=3))
    n = len(late["obs"])
    assert np.array_equal(late["obs"][3:], bare["obs"][: n - 3])
    assert all(np.array_equal(o, bare["obs"][0]) for o in late["obs"][:4])


def test_action_delay_executes_the_action_of_k_steps_ago():
    late = run(ActionDelay(RobustHopper(), steps=2))
    # realworldrl_suite's buffer starts full of the first action (realworld_env.py:57-66)
    np.testing.assert_array_equal(late["ctrl"][:3], [ACTIONS[0]] * 3)
    n = len(late["ctrl"])
    np.testing.assert_array_equal(late["ctrl"][2:], ACTIONS[: n - 2])
    # the physics is that of the delayed actions on the bare env
    shifted = np.concatenate([[ACTIONS[0]] * 2, ACTIONS[:-2]])
    assert np.array_equal(run(RobustHopper(), actions=shifted)["qpos"][:n], late["qpos"])


def test_action_delay_prefills_each_episode_with_its_own_first_action():
    env = ActionDelay(RobustHopper(), steps=3)
    for episode, first in enumerate((0.25, -0.75)):
        env.reset(seed=episode)
        acts = [first, 0.5, -0.5, 0.1, 0.2]
        executed = [float(env.step(np.full(3, a))[-1]["executed_action"][0]) for a in acts]
        assert executed == [first, first, first, first, 0.5], episode


def test_action_noise_reaches_mujoco_and_stays_in_bounds():
    noisy = run(ActionNoise(RobustHopper(), std=0.3))
    executed = np.array([i["executed_action"] for i in noisy["info"]])
    assert np.array_equal(noisy["ctrl"], executed)  # what MuJoCo got
    n = len(executed)
    assert np.all(executed != ACTIONS[:n])
    assert np.all(np.abs(executed) <= 1.0)
    assert not np.array_equal(noisy["qpos"], run(RobustHopper())["qpos"][:n])


def test_reward_noise_reaches_the_reward_only():
    bare = run(RobustHopper())
    noisy = run(RewardNoise(RobustHopper(), std=2.0))
    true = np.array([i["true_reward"] for i in noisy["info"]])
    assert np.array_equal(true, bare["reward"]) and np.array_equal(noisy["qpos"], bare["qpos"])
    assert 1.5 < (noisy["reward"] - true).std() < 2.5


def test_seeds_reproduce_and_streams_are_independent():
    make = lambda: disrupt(RobustHopper(), obsnoise=0.1, actionnoise=0.2, rewardnoise=1.0)  # noqa: E731
    a, b, c = run(make(), seed=4), run(make(), seed=4), run(make(), seed=5)
    for key in ("obs", "reward", "qpos"):
        assert np.array_equal(a[key], b[key])
        assert not np.array_equal(a[key][:5], c[key][:5])
    # unseeded resets continue the seeded sequence the same way
    env1, env2 = make(), make()
    env1.reset(seed=9)
    env2.reset(seed=9)
    assert np.array_equal(env1.reset()[0], env2.reset()[0])
    # the initial state is the bare env's: spawning draws nothing from env.np_random
    bare = RobustHopper()
    bare.reset(seed=4)
    env = disrupt(RobustHopper(), actionnoise=0.5)
    env.reset(seed=4)
    assert np.array_equal(bare.data.qpos, env.unwrapped.data.qpos)


@pytest.mark.parametrize(
    "name, bad",
    [
        ("obsnoise", -0.1),
        ("actionnoise", np.nan),
        ("rewardnoise", np.inf),
        ("obsdropout", 1.5),
        ("obsstuck", -0.01),
        ("obsdelay", 1.5),
        ("actiondelay", -1),
        ("obsnoise", "loud"),
    ],
)
def test_bad_strengths_are_refused_in_one_line(name, bad):
    for attempt in (
        lambda: disrupt(RobustHopper(), **{name: bad}),
        lambda: disrupt(RobustHopper(), **{name: 0}).set_params(**{name: bad}),
        lambda: DomainRandomization(disrupt(RobustHopper(), **{name: 0}), {name: (bad, 1)}),
    ):
        with pytest.raises(ValueError, match=f"{name}|bounds must be") as err:
            attempt()
        assert "\n" not in str(err.value)


def test_unknown_disruptors_and_options():
    with pytest.raises(ValueError, match="unknown disruptor.*valid: actionnoise"):
        disrupt(RobustHopper(), noise=0.1)
    with pytest.raises(ValueError, match="duration"):
        ObservationDropout(RobustHopper(), 0.1, duration=0)


def test_strengths_are_parameters_like_any_other():
    env = disrupt(RobustHopper(), obsnoise=0.0, obsdelay=1)
    params = env.get_params()
    assert params["obsnoise"] == 0.0 and params["obsdelay"] == 1.0 and "torsomass" in params
    with pytest.raises(ValueError):  # validated before anything is written
        env.set_params(torsomass=2.0, obsnoise=-1.0)
    assert env.get_params()["torsomass"] == params["torsomass"]
    env.set_params(torsomass=2.0, obsnoise=0.2)
    assert env.get_params()["torsomass"] == 2.0 and env.get_params()["obsnoise"] == 0.2
    env.reset_params()
    assert env.get_params() == params
    _, info = env.reset(seed=0, options={"obsnoise": 0.3, "torsomass": 1.5})
    assert env.get_params()["obsnoise"] == 0.3 and info["torsomass"] == 1.5
    # domain randomization draws a strength; the adversary plays one; context shows one
    dr = DomainRandomization(disrupt(RobustHopper(), obsnoise=0), {"obsnoise": (0.0, 0.5)})
    _, info = dr.reset(seed=1)
    assert 0 <= info["randomized_params"]["obsnoise"] <= 0.5
    assert dr.get_params()["obsnoise"] == info["randomized_params"]["obsnoise"]
    game = DynamicAdversarial(disrupt(RobustHopper(), actionnoise=0), {"actionnoise": (0, 1)})
    game.reset(seed=0)
    *_, info = game.step((np.zeros(3), np.array([1.0])))
    assert game.get_params() == {"actionnoise": 1.0} and np.any(info["executed_action"] != 0)
    seen = ContextObservation(disrupt(RobustHopper(), obsnoise=0.25), {"obsnoise": (0, 0.5)})
    assert seen.reset(seed=0)[0][-1] == 0.0


def test_registered_envs_take_disruptors():
    env = disrupt(gym.make("rrls/robust-walker-v0"), obsnoise=0.1)
    env.set_params(worldfriction=0.5)
    assert env.get_params()["worldfriction"] == 0.5
    obs, *_ = env.step(np.zeros(6)) if env.reset(seed=0) else None
    assert obs.shape == (17,)
