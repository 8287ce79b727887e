"""Schedules over time and context in the observation."""

from __future__ import annotations

import math

import numpy as np
import pytest

from rrls.envs import RobustHopper
from rrls.uncertainty import UncertaintySet
from rrls.wrappers import (
    ContextObservation,
    DomainRandomization,
    Drift,
    DynamicAdversarial,
    RandomWalk,
    ScheduledParams,
    ScheduleFamily,
    Sinusoid,
    StepChange,
    disrupt,
)

BOX = UncertaintySet.from_bounds({"torsomass": (1.0, 5.0), "worldfriction": (0.5, 1.5)})


def path(env, steps=30, seed=0):
    """The normalised parameter point in force at each step, and the trajectory."""
    env.reset(seed=seed)
    points, qpos = [], []
    for _ in range(steps):
        *_, term, trunc, info = env.step(np.full(3, 0.1))
        points.append(BOX.normalize(BOX.to_array(info["scheduled_params"])))
        qpos.append(env.unwrapped.data.qpos.copy())
        if term or trunc:
            break
    return np.array(points), np.array(qpos)


def start():
    return BOX.normalize(BOX.to_array({k: RobustHopper().get_params()[k] for k in BOX.names}))


def test_drift_moves_at_its_rate_and_stops_at_the_edge():
    points, qpos = path(ScheduledParams(RobustHopper(), BOX, Drift(rate=0.05, direction=(1, -1))))
    t = np.arange(1, len(points) + 1)[:, None]
    expected = np.clip(start() + t * 0.05 * np.array([1, -1]), -1, 1)
    np.testing.assert_allclose(points, expected, atol=1e-12)
    assert points[-1, 1] == -1.0  # friction reached its lower bound and stays there
    _, bare = path(ScheduledParams(RobustHopper(), BOX, Drift(rate=0.0)))
    assert not np.array_equal(qpos, bare[: len(qpos)])  # the parameters reach the physics


def test_sinusoid_and_step_change_follow_their_formulas():
    points, _ = path(ScheduledParams(RobustHopper(), BOX, Sinusoid(0.2, period=8, phase=0.5)))
    for t, p in enumerate(points, start=1):
        wave = 0.2 * math.sin(2 * math.pi * t / 8 + 0.5)
        np.testing.assert_allclose(p, np.clip(start() + wave, -1, 1), atol=1e-12)
    points, _ = path(ScheduledParams(RobustHopper(), BOX, StepChange(at=5, to=(-0.5, 0.5))))
    np.testing.assert_allclose(points[:4], np.tile(start(), (4, 1)), atol=1e-12)
    np.testing.assert_allclose(points[4:], np.tile([-0.5, 0.5], (len(points) - 4, 1)))


def test_random_walk_is_seeded_and_has_its_step_size():
    make = lambda: ScheduledParams(RobustHopper(), BOX, RandomWalk(std=0.02))  # noqa: E731
    a, b, c = path(make(), seed=1)[0], path(make(), seed=1)[0], path(make(), seed=2)[0]
    assert np.array_equal(a, b) and not np.array_equal(a[:5], c[:5])
    steps = np.diff(np.vstack([start(), a]), axis=0)
    assert 0.01 < steps.std() < 0.03
    still, _ = path(ScheduledParams(RobustHopper(), BOX, RandomWalk(std=0.0)))
    assert np.all(still == still[0])


def test_schedule_starts_from_the_episode_draw_and_fields_are_parameters():
    env = DomainRandomization(ScheduledParams(RobustHopper(), BOX, Drift(rate=0.01)), BOX)
    _, info = env.reset(seed=3)
    first = BOX.normalize(BOX.to_array(info["randomized_params"]))
    *_, info = env.step(np.zeros(3))
    got = BOX.normalize(BOX.to_array(info["scheduled_params"]))
    np.testing.assert_allclose(got, np.clip(first + 0.01, -1, 1), atol=1e-12)
    inner = ScheduledParams(RobustHopper(), BOX, Drift(rate=0.01))
    assert {"drift_rate": 0.01, "drift_direction": 1.0}.items() <= inner.get_params().items()
    inner.set_params(drift_rate=-0.02, torsomass=2.0)
    assert inner.schedule == Drift(rate=-0.02) and inner.get_params()["torsomass"] == 2.0
    inner.reset_params()
    assert inner.schedule == Drift(rate=0.01)
    # a schedule's field spans a set like any parameter: randomised per episode
    dr = DomainRandomization(inner, {"drift_rate": (0.0, 0.1)})
    _, info = dr.reset(seed=0)
    assert inner.schedule.rate == info["randomized_params"]["drift_rate"]


@pytest.mark.parametrize(
    "make, match",
    [
        (lambda: Drift(rate=float("nan")), "drift_rate must be finite"),
        (lambda: RandomWalk(std=-1), "walk_std .* >= 0"),
        (lambda: Sinusoid(period=0), "sine_period .* > 0"),
        (lambda: StepChange(at=1.5), "step_at .* whole number"),
        (lambda: StepChange(to=2.0), r"step_to .* \[-1, 1\]"),
        (
            lambda: ScheduledParams(RobustHopper(), BOX, Drift(direction=(1, 1, 1))),
            "drift_direction has 3 values; the set has 2",
        ),
        (lambda: ScheduledParams(RobustHopper(), {}, Drift()), "at least one parameter"),
        (lambda: ScheduledParams(RobustHopper(), BOX, "drift"), "schedule must be one of"),
        (lambda: ScheduleFamily("wobble", rate=[1]), "unknown schedule 'wobble'"),
        (lambda: ScheduleFamily("drift", speed=[1]), r"drift has no field\(s\) \['speed'\]"),
        (lambda: ScheduleFamily("randomwalk", std=[0.1, -1]), "walk_std"),
    ],
)
def test_bad_schedules_are_refused_in_one_line(make, match):
    with pytest.raises((ValueError, TypeError), match=match) as err:
        make()
    assert "\n" not in str(err.value)


def test_schedule_family_grid():
    family = ScheduleFamily("sinusoid", amplitude=[0.1, 0.2, 0.3], period=50)
    assert family.names == ("sine_amplitude", "sine_period")
    assert family.points().shape == (3, 2) and family.schedule == Sinusoid()


# -- context ---------------------------------------------------------------------------------
def test_context_observation_appends_the_normalised_parameters():
    base = RobustHopper(torsomass=2.0)
    env = ContextObservation(base, BOX)
    assert env.observation_space.shape == (13,)
    assert np.all(env.observation_space.low[-2:] == -1) and np.all(
        env.observation_space.high[-2:] == 1
    )
    obs, _ = env.reset(seed=0)
    clean, _ = RobustHopper(torsomass=2.0).reset(seed=0)
    assert np.array_equal(obs[:-2], clean)
    np.testing.assert_allclose(obs[-2:], BOX.normalize([2.0, base.get_params()["worldfriction"]]))
    assert env.observation_space.contains(obs.astype(env.observation_space.dtype))


def test_context_follows_the_adversary_and_the_schedule():
    target = DynamicAdversarial(RobustHopper(), BOX, rate_limit=0.1, rate_game="target")
    seen = ContextObservation(target, BOX)
    seen.reset(seed=0)
    for _ in range(5):
        obs, *_, info = seen.step((np.zeros(3), np.array([1.0, -1.0])))
        np.testing.assert_allclose(obs[-2:], info["normalized_params"], atol=1e-9)
    drifting = ContextObservation(ScheduledParams(RobustHopper(), BOX, Drift(rate=0.05)), BOX)
    drifting.reset(seed=0)
    obs, *_, info = drifting.step(np.zeros(3))
    np.testing.assert_allclose(obs[-2:], np.clip(start() + 0.05, -1, 1), atol=1e-12)
    noisy = ContextObservation(disrupt(RobustHopper(), obsnoise=0.1), {"obsnoise": (0, 0.2)})
    assert noisy.reset(seed=0)[0][-1] == 0.0


def test_aliases_are_read_through_their_parameter():
    from rrls.envs import ForceHopper

    alias = {"torsoforce_z": (-2.0, 2.0)}  # on planar tasks _z is an alias of _y (vertical)
    seen = ContextObservation(ForceHopper(torsoforce_y=1.0), alias)
    assert seen.reset(seed=0)[0][-1] == 0.5
    game = DynamicAdversarial(ForceHopper(), alias, rate_limit=0.1, rate_game="target")
    _, info = game.reset(seed=0)
    assert info["normalized_params"].tolist() == [0.0]
    drift = ScheduledParams(ForceHopper(), alias, Drift(rate=0.25))
    drift.reset(seed=0)
    *_, info = drift.step(np.zeros(3))
    assert info["scheduled_params"] == {"torsoforce_z": 0.5}
