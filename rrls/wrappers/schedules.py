"""Schedules over time: the parameters of a set move within an episode (realworldrl_suite's
perturbation schedulers, Robust-Gymnasium's non-stationary envs).

A schedule is a small frozen dataclass that says where the parameters are at step ``t``, in the
set's normalised units (``[-1, 1]`` per axis, so one schedule fits any set); the result is
clipped into the set. ``start`` is the point in force after ``reset`` (the nominal model, a
``DomainRandomization`` draw, or ``reset(options=...)``), clipped into the set.

=============  ============================================  ======================================
schedule       x(t) (normalised; step t = 1, 2, ...)         fields (parameter names, units)
=============  ============================================  ======================================
Drift          ``start + t * rate * direction``              ``drift_rate`` (per step),
                                                             ``drift_direction`` (sign or vector)
RandomWalk     ``x(t-1) + N(0, std^2)`` per axis             ``walk_std`` (per step)
Sinusoid       ``start + amplitude * direction *             ``sine_amplitude``, ``sine_period``
               sin(2 pi t / period + phase)``                (steps, > 0), ``sine_phase`` (rad),
                                                             ``sine_direction``
StepChange     ``start`` before step ``at``, ``to`` from it  ``step_at`` (steps), ``step_to``
                                                             (normalised point, in [-1, 1])
=============  ============================================  ======================================

A schedule's scalar fields are parameters of :class:`ScheduledParams` like any other (the names
above): ``set_params(drift_rate=0.01)`` changes it, an ``UncertaintySet`` can span them, and
``evaluate(..., schedule=ScheduleFamily(...))`` meshes over them (e.g. drift rate x direction).
"""

from __future__ import annotations

import dataclasses
import itertools
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, ClassVar

import gymnasium as gym
import numpy as np

from rrls.uncertainty import UncertaintySet
from rrls.wrappers._checks import check_names, read_point, refuse_empty
from rrls.wrappers.access import ParamsForwarding
from rrls.wrappers.disruptors import spawn_generator

Direction = float | tuple[float, ...]


def _real(name: str, value: Any) -> float:
    if isinstance(value, np.ndarray) and value.size == 1:
        value = value.item()
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise ValueError(f"{name} must be a real number, got {value!r}")
    if not math.isfinite(value):
        raise ValueError(f"{name} must be finite, got {value!r}")
    return float(value)


def _direction(name: str, value: Any) -> Direction:
    if np.ndim(value) == 0:
        return _real(name, value)
    values = tuple(_real(name, v) for v in np.asarray(value, dtype=object).reshape(-1))
    if not values:
        raise ValueError(f"{name} must not be empty")
    return values


class Schedule:
    """Base class: ``prefix`` names the parameters (``<prefix>_<field>``)."""

    prefix: ClassVar[str]

    def value(
        self, t: int, start: np.ndarray, previous: np.ndarray, rng: np.random.Generator
    ) -> np.ndarray:
        raise NotImplementedError

    def params(self) -> dict[str, float]:
        """The scalar fields as parameters (``drift_rate`` ...)."""
        out = {}
        for f in dataclasses.fields(self):
            v = getattr(self, f.name)
            if np.ndim(v) == 0:
                out[f"{self.prefix}_{f.name}"] = float(v)
        return out

    def with_params(self, **params: float) -> Schedule:
        """A copy with some fields replaced, by parameter name (validated)."""
        fields = {f"{self.prefix}_{f.name}": f.name for f in dataclasses.fields(self)}
        unknown = [k for k in params if k not in fields]
        if unknown:
            raise ValueError(f"unknown schedule parameter(s) {unknown}; valid: {', '.join(fields)}")
        return dataclasses.replace(self, **{fields[k]: v for k, v in params.items()})

    def _check_dims(self, dim: int) -> None:
        for f in dataclasses.fields(self):
            v = getattr(self, f.name)
            if isinstance(v, tuple) and len(v) not in (1, dim):
                raise ValueError(
                    f"{self.prefix}_{f.name} has {len(v)} values; the set has {dim} parameters"
                )

    def to_json(self) -> dict[str, Any]:
        return {"schedule": type(self).__name__, **dataclasses.asdict(self)}


@dataclass(frozen=True)
class Drift(Schedule):
    """Constant velocity ``rate * direction`` per step (normalised units), stopping at the set's
    edge. ``direction``: a sign/scale for every axis, or one value per parameter."""

    rate: float = 0.0
    direction: Direction = 1.0
    prefix: ClassVar[str] = "drift"

    def __post_init__(self) -> None:
        object.__setattr__(self, "rate", _real("drift_rate", self.rate))
        object.__setattr__(self, "direction", _direction("drift_direction", self.direction))

    def value(self, t, start, previous, rng):  # see Schedule
        return start + t * self.rate * np.asarray(self.direction, dtype=np.float64)


@dataclass(frozen=True)
class RandomWalk(Schedule):
    """Gaussian steps of standard deviation ``std`` per axis and step, clipped to the set."""

    std: float = 0.0
    prefix: ClassVar[str] = "walk"

    def __post_init__(self) -> None:
        std = _real("walk_std", self.std)
        if std < 0:
            raise ValueError(f"walk_std is a standard deviation and must be >= 0, got {std!r}")
        object.__setattr__(self, "std", std)

    def value(self, t, start, previous, rng):  # see Schedule
        if self.std == 0:
            return previous
        return previous + rng.normal(0.0, self.std, previous.shape)


@dataclass(frozen=True)
class Sinusoid(Schedule):
    """Oscillation around the start: ``amplitude * direction * sin(2 pi t / period + phase)``."""

    amplitude: float = 0.0
    period: float = 100.0
    phase: float = 0.0
    direction: Direction = 1.0
    prefix: ClassVar[str] = "sine"

    def __post_init__(self) -> None:
        object.__setattr__(self, "amplitude", _real("sine_amplitude", self.amplitude))
        period = _real("sine_period", self.period)
        if period <= 0:
            raise ValueError(f"sine_period is a number of steps and must be > 0, got {period!r}")
        object.__setattr__(self, "period", period)
        object.__setattr__(self, "phase", _real("sine_phase", self.phase))
        object.__setattr__(self, "direction", _direction("sine_direction", self.direction))

    def value(self, t, start, previous, rng):  # see Schedule
        wave = math.sin(2.0 * math.pi * t / self.period + self.phase)
        return start + self.amplitude * wave * np.asarray(self.direction, dtype=np.float64)


@dataclass(frozen=True)
class StepChange(Schedule):
    """The start until step ``at`` (excluded), then the normalised point ``to``."""

    at: float = 0.0
    to: Direction = 0.0
    prefix: ClassVar[str] = "step"

    def __post_init__(self) -> None:
        at = _real("step_at", self.at)
        if not (at.is_integer() and at >= 0):
            raise ValueError(f"step_at is a step number and must be a whole number >= 0, got {at}")
        to = _direction("step_to", self.to)
        if not np.all(np.abs(np.asarray(to)) <= 1.0):
            raise ValueError(f"step_to is a normalised point and must be in [-1, 1], got {to}")
        object.__setattr__(self, "at", at)
        object.__setattr__(self, "to", to)

    def value(self, t, start, previous, rng):  # see Schedule
        if t < self.at:
            return start
        return np.broadcast_to(np.asarray(self.to, dtype=np.float64), start.shape).copy()


SCHEDULES: dict[str, type[Schedule]] = {
    "drift": Drift,
    "randomwalk": RandomWalk,
    "sinusoid": Sinusoid,
    "stepchange": StepChange,
}


class ScheduledParams(ParamsForwarding, gym.utils.RecordConstructorArgs):
    """The parameters of ``params_bound`` follow ``schedule`` within each episode.

    Before step ``t`` the parameters are set to the schedule's point ``x(t)`` (clipped into the
    set); ``info["scheduled_params"]`` holds them. Randomness (``RandomWalk``) comes from a
    generator spawned at each ``reset`` from the env's seeded ``np_random``. The schedule's
    scalar fields are parameters of this wrapper (``drift_rate`` ...; see the module table).

    >>> import numpy as np
    >>> from rrls.envs import RobustHopper
    >>> from rrls.wrappers.schedules import Drift, ScheduledParams
    >>> env = ScheduledParams(RobustHopper(), {"torsomass": (1.0, 5.0)}, Drift(rate=0.01))
    >>> _ = env.reset(seed=0)  # nominal torso mass 3.67 is 0.335 in normalised units
    >>> masses = [env.step(np.zeros(3))[-1]["torsomass"] for _ in range(3)]
    >>> [round(m - masses[0], 3) for m in masses]  # +0.01 * (5 - 1) / 2 = +0.02 kg per step
    [0.0, 0.02, 0.04]
    """

    def __init__(
        self,
        env: gym.Env,
        params_bound: Mapping[str, Sequence[float]] | UncertaintySet,
        schedule: Schedule,
    ) -> None:
        gym.utils.RecordConstructorArgs.__init__(self, params_bound=params_bound, schedule=schedule)
        super().__init__(env)
        if not isinstance(schedule, Schedule):
            raise TypeError(
                f"schedule must be one of {', '.join(c.__name__ for c in SCHEDULES.values())}, "
                f"got {type(schedule).__name__}"
            )
        self.uncertainty_set = UncertaintySet.from_bounds(params_bound)
        refuse_empty(self.uncertainty_set, "ScheduledParams", self.env)
        check_names(self.env, self.uncertainty_set)
        schedule._check_dims(self.uncertainty_set.dim)
        taken = [n for n in schedule.params() if n in self.env.get_wrapper_attr("get_params")()]
        if taken:  # a second schedule of one kind: set_params would reach only the outer one
            raise ValueError(
                f"ScheduledParams: the env already has the parameter(s) {taken} (it is "
                f"scheduled by a {type(schedule).__name__} already); schedule each kind once"
            )
        self._initial = schedule
        self.schedule = schedule
        self.rng = np.random.default_rng(0)  # replaced at every reset
        self._t = 0
        self._start = self._x = np.zeros(self.uncertainty_set.dim)
        self._start_values = self._start
        self._raw_start: dict[str, float] = {}
        #: the values the schedule overwrote (the episode's start, as read at reset), put back
        #: at the next reset so that each episode starts where it would without the schedule
        self._moved: dict[str, float] = {}
        specs = getattr(self.env.unwrapped, "param_specs", ())
        self._canonical = {a: s.name for s in specs for a in s.aliases}

    # -- parameters ---------------------------------------------------------------------------
    def own_params(self) -> dict[str, float]:
        return self.schedule.params()

    def check_param(self, name: str, value: float) -> str | None:
        try:
            self.schedule.with_params(**{name: value})
        except ValueError as err:
            return str(err)
        return None

    def get_params(self, kinds: Any = None) -> dict[str, float]:
        """The inner env's parameters (``kinds`` forwarded) and this wrapper's own, always."""
        return {**ParamsForwarding.get_params(self, kinds), **self.own_params()}

    def set_params(self, **params: float) -> None:
        fields = {f"{self.schedule.prefix}_{f.name}" for f in dataclasses.fields(self.schedule)}
        mine = {k: params.pop(k) for k in list(params) if k in fields}
        schedule = self.schedule.with_params(**mine) if mine else self.schedule  # validates
        if params:
            self.env.get_wrapper_attr("set_params")(**params)
            given = {self._canonical.get(k, k) for k in params}  # set by the caller: kept
            self._moved = {
                k: v for k, v in self._moved.items() if self._canonical.get(k, k) not in given
            }
        self.schedule = schedule

    def reset_params(self) -> None:
        self.schedule = self._initial
        self.env.get_wrapper_attr("reset_params")()

    # -- Gymnasium hooks ----------------------------------------------------------------------
    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        """A new episode: the schedule restarts from the values in force before it moved them
        (or from ``options`` / an inner draw); a refused reset changes nothing."""
        schedule, moved = self.schedule, self._moved
        if options:
            mine = set(self.own_params())
            if mine & set(options):
                self.set_params(**{k: v for k, v in options.items() if k in mine})
                options = {k: v for k, v in options.items() if k not in mine} or None
        box = self.uncertainty_set
        inner_set = self.env.get_wrapper_attr("set_params")
        scheduled = box.to_dict(read_point(self.env, box)) if moved else {}
        try:
            if moved:
                inner_set(**moved)
            obs, info = self.env.reset(seed=seed, options=options)
        except BaseException:  # put back the schedule and its point
            self.schedule = schedule
            if scheduled:
                inner_set(**scheduled)
            raise
        self._moved = {}
        raw = read_point(self.env, box)
        self._start_values = box.clip(raw)
        self._raw_start = box.to_dict(raw)
        self._start = self._x = box.normalize(self._start_values)
        self.rng = spawn_generator(self.env)
        self._t = 0
        info["scheduled_params"] = box.to_dict(self._start_values)
        return obs, info

    def step(self, action: Any):
        self._t += 1
        box = self.uncertainty_set
        x = np.clip(self.schedule.value(self._t, self._start, self._x, self.rng), -1.0, 1.0)
        self._x = x
        # where the point is the start, the start's own values (no normalisation round trip)
        values = np.where(x == self._start, self._start_values, box.denormalize(x))
        point = box.to_dict(np.clip(values, box.low, box.high))
        if not self._moved:
            self._moved = self._raw_start
        self.env.get_wrapper_attr("set_params")(**point)
        obs, reward, terminated, truncated, info = self.env.step(action)
        info["scheduled_params"] = point
        return obs, reward, terminated, truncated, info


@dataclass(frozen=True)
class ScheduleFamily:
    """A grid of schedules of one kind: each field takes each of its listed values.

    ``ScheduleFamily("drift", rate=[0.001, 0.002, 0.004], direction=[-1, 1])`` is the six drifts
    of three rates in both directions; fields not listed keep the schedule's default.

    >>> from rrls.wrappers.schedules import ScheduleFamily
    >>> family = ScheduleFamily("drift", rate=[0.001, 0.002], direction=[-1, 1])
    >>> family.names, family.points().tolist()
    (('drift_rate', 'drift_direction'), [[0.001, -1.0], [0.001, 1.0], [0.002, -1.0], [0.002, 1.0]])
    """

    kind: str
    grid: dict[str, tuple[float, ...]]

    def __init__(self, kind: str, **values: Sequence[float] | float) -> None:
        if kind not in SCHEDULES:
            raise ValueError(f"unknown schedule {kind!r}; valid: {', '.join(SCHEDULES)}")
        cls = SCHEDULES[kind]
        fields = [f.name for f in dataclasses.fields(cls)]
        unknown = [k for k in values if k not in fields]
        if unknown:
            raise ValueError(f"{kind} has no field(s) {unknown}; valid: {', '.join(fields)}")
        grid = {}
        for k, v in values.items():
            vals = tuple(float(x) for x in np.atleast_1d(np.asarray(v, dtype=np.float64)))
            if not vals:
                raise ValueError(f"{kind} {k} needs at least one value")
            for x in vals:  # each value is checked by the schedule itself
                cls(**{k: x})
            grid[k] = vals
        if not grid:
            raise ValueError(f"give the values of at least one field of {kind}: {fields}")
        object.__setattr__(self, "kind", kind)
        object.__setattr__(self, "grid", grid)

    @property
    def schedule(self) -> Schedule:
        """The schedule with default fields (the grid's values are set per point)."""
        return SCHEDULES[self.kind]()

    @property
    def names(self) -> tuple[str, ...]:
        prefix = SCHEDULES[self.kind].prefix
        return tuple(f"{prefix}_{k}" for k in self.grid)

    def points(self) -> np.ndarray:
        """Every combination, first field varying slowest: shape ``(n, len(names))``."""
        rows = list(itertools.product(*self.grid.values()))
        return np.array(rows, dtype=np.float64).reshape(len(rows), len(self.grid))

    def __hash__(self) -> int:
        return hash((self.kind, tuple(self.grid.items())))

    def to_json(self) -> dict[str, Any]:
        return {"kind": self.kind, "grid": {k: list(v) for k, v in self.grid.items()}}


__all__ = [
    "Direction",
    "Drift",
    "RandomWalk",
    "Schedule",
    "ScheduledParams",
    "ScheduleFamily",
    "SCHEDULES",
    "Sinusoid",
    "StepChange",
]
