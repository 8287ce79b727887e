"""Outside probes of disruptors, schedules and splits (issue 26): bad input is refused in one
line and changes nothing; schedules restart every episode; a split always has a training part."""

from __future__ import annotations

import re

import numpy as np
import pytest

import rrls  # noqa: F401
from rrls.envs import RobustHopper
from rrls.uncertainty import Split, UncertaintySet
from rrls.wrappers import (
    DISRUPTORS,
    ActionDelay,
    ContextObservation,
    DomainRandomization,
    ObservationNoise,
)
from rrls.wrappers.schedules import Drift, RandomWalk, ScheduledParams, Sinusoid

BOX = {"torsomass": (1.0, 9.0)}


def _valid(name: str) -> float:
    return 1 if DISRUPTORS[name].kind == "steps" else 0.05


@pytest.mark.parametrize("name", list(DISRUPTORS))
def test_none_is_not_a_strength(name):
    env = DISRUPTORS[name](RobustHopper(), _valid(name))
    with pytest.raises(ValueError, match=f"{name} must be a real number, got None"):
        env.set_params(**{name: None})
    with pytest.raises(ValueError, match=f"{name} must be a real number, got None"):
        env.reset(seed=0, options={name: None})
    assert env.get_params()[name] == _valid(name)


@pytest.mark.parametrize("name", list(DISRUPTORS))
def test_a_refused_reset_changes_no_strength(name):
    env = DISRUPTORS[name](RobustHopper())
    with pytest.raises(ValueError, match="torsomass"):
        env.reset(seed=0, options={name: _valid(name), "torsomass": -1.0})
    assert env.get_params()[name] == 0
    with pytest.raises(ValueError, match="torsomass"):
        env.set_params(**{name: _valid(name), "torsomass": -1.0})
    assert env.get_params()[name] == 0


@pytest.mark.parametrize("name", ["obsnoise", "actionnoise", "rewardnoise"])
@pytest.mark.parametrize("bad", [1e308, 1e7])
def test_absurd_noise_is_refused_with_its_range(name, bad):
    message = rf"{name} .* must be in \[0, 1000000\], got {re.escape(repr(bad))}"
    with pytest.raises(ValueError, match=message):
        DISRUPTORS[name](RobustHopper(), bad)
    env = DISRUPTORS[name](RobustHopper())
    with pytest.raises(ValueError, match=r"\[0, 1000000\]"):
        env.set_params(**{name: bad})
    DISRUPTORS[name](RobustHopper(), 1e6)  # the largest accepted


@pytest.mark.parametrize("cls", [ObservationNoise, ActionDelay])
def test_a_disruptor_wraps_a_stack_once(cls):
    with pytest.raises(ValueError, match=f"already has the parameter '{cls.param}'.*once"):
        cls(cls(RobustHopper()))
    with pytest.raises(ValueError, match="once"):  # also with another wrapper in between
        cls(DomainRandomization(cls(RobustHopper()), {"torsomass": (2.0, 4.0)}))


def _masses(env: ScheduledParams, steps: int = 60) -> tuple[float, list[float]]:
    _, info = env.reset(seed=0)
    seen = [env.step(np.zeros(3))[-1]["scheduled_params"]["torsomass"] for _ in range(steps)]
    return info["scheduled_params"]["torsomass"], seen


@pytest.mark.parametrize(
    "schedule", [Drift(rate=0.02), RandomWalk(std=0.1), Sinusoid(amplitude=0.5, period=7)]
)
@pytest.mark.parametrize("context", [False, True])
def test_schedules_restart_every_episode(schedule, context):
    env = ScheduledParams(RobustHopper(), BOX, schedule)
    if context:
        env = ContextObservation(env, BOX)
    first = _masses(env)
    assert first[1][-1] != first[0]  # the schedule moved the mass
    assert _masses(env) == first  # the same seed: the same episode, from the same start
    nominal = RobustHopper().get_params()["torsomass"]
    assert first[0] == nominal


def test_a_schedule_keeps_what_the_caller_sets_between_episodes():
    env = ScheduledParams(RobustHopper(), BOX, Drift(rate=0.02))
    _masses(env)
    env.set_params(torsomass=2.0)
    assert _masses(env)[0] == 2.0
    start, _ = _masses(env)
    assert start == 2.0  # and the next episode starts there again
    _, info = env.reset(seed=0, options={"torsomass": 5.0})
    assert info["scheduled_params"]["torsomass"] == 5.0


def test_a_schedule_inside_domain_randomization_starts_from_each_draw():
    env = DomainRandomization(
        ScheduledParams(RobustHopper(), BOX, Drift(rate=0.05)), {"torsomass": (2.0, 3.0)}
    )
    for _ in range(3):
        _, info = env.reset()
        assert 2.0 <= info["scheduled_params"]["torsomass"] <= 3.0
        for _ in range(30):
            env.step(np.zeros(3))


def test_a_refused_reset_changes_no_schedule_field_nor_point():
    env = ScheduledParams(RobustHopper(), BOX, Drift(rate=0.01))
    _masses(env, 10)
    moved = env.get_params()["torsomass"]
    with pytest.raises(ValueError, match="torsomass"):
        env.reset(seed=0, options={"drift_rate": 0.5, "torsomass": -1.0})
    assert env.get_params()["drift_rate"] == 0.01
    assert env.get_params()["torsomass"] == moved
    with pytest.raises(ValueError, match="drift_rate must be a real number, got None"):
        env.set_params(drift_rate=None)


def test_a_schedule_kind_wraps_a_stack_once():
    inner = ScheduledParams(RobustHopper(), BOX, Drift(rate=0.01))
    with pytest.raises(ValueError, match="drift_rate.*once"):
        ScheduledParams(inner, BOX, Drift(rate=0.02))
    ScheduledParams(inner, BOX, RandomWalk(std=0.01))  # another kind: its own parameters


def test_a_split_without_training_part_is_refused():
    box = UncertaintySet.from_bounds({"torsomass": (1.0, 5.0), "thighmass": (1.0, 2.0)})
    with pytest.raises(ValueError, match="training part is empty"):
        Split.interpolation(box, box.as_bounds())
    with pytest.raises(ValueError, match="training part is empty"):
        Split.interpolation(box, 1 - 1e-9)
    with pytest.raises(ValueError, match="training part is empty"):
        Split.from_json({**Split.interpolation(box).to_json(), "region_low": [1.0, 1.0],
                         "region_high": [5.0, 2.0]})  # fmt: skip
    point = UncertaintySet.from_bounds({"torsomass": (3.0, 3.0)})
    with pytest.raises(ValueError, match="training part is empty"):
        Split.interpolation(point, 0.5)
    ok = Split.interpolation(box, {"torsomass": (1.0, 5.0), "thighmass": (1.0, 1.5)})
    assert ok.train_fraction() == 0.5
    draw = ok.sample_train(box, np.random.default_rng(0))
    assert draw["thighmass"] > 1.5
