"""Disruptors: what goes wrong between the agent and the physics.

Six of realworldrl_suite's perturbations (Dulac-Arnold et al., ``realworld_env.py`` at be7a51c),
with its semantics: Gaussian observation and action noise (``:439``, ``:551``), dropped and
stuck observations (``:446``, ``:468``), observation and action delays, both pre-filled with the
episode's first observation or action (``delayed_buffer_item``, ``:57-66``; realworldrl_suite
keeps its buffers across episodes, rrls starts each episode afresh). Reward noise is rrls's own:
realworldrl_suite has none. realworldrl_suite's reward delay (``:521``), dropped and stuck
actions (``:556``, ``:573``) and action repetition (``:598``) are not in rrls.

One wrapper per behaviour. Each adds **one parameter**, its strength, to the env's
``set_params``/``get_params`` (so an :class:`~rrls.uncertainty.UncertaintySet` can span it, and
domain randomization, the adversary, schedules, ``ContextObservation`` and ``evaluate`` treat it
like a mass or a friction):

==============  ====================  ============================================  ===========
parameter       wrapper               meaning (units)                               valid
==============  ====================  ============================================  ===========
``obsnoise``    ObservationNoise      std of Gaussian noise on every observation    [0, 1e6]
                                      component (observation units)
``obsdropout``  ObservationDropout    probability that a component reads 0 at a     [0, 1]
                                      step (for ``duration`` steps)
``obsstuck``    StuckSensors          probability that a component freezes at its   [0, 1]
                                      last value (for ``duration`` steps)
``obsdelay``    ObservationDelay      the agent sees the observation of ``k``       whole >= 0
                                      steps ago (steps)
``actionnoise`` ActionNoise           std of Gaussian noise on every action         [0, 1e6]
                                      component (action units, clipped to bounds)
``actiondelay`` ActionDelay           the env executes the action of ``k`` steps    whole >= 0
                                      ago; the first one before that (steps)
``rewardnoise`` RewardNoise           std of Gaussian noise on the reward (rrls's   [0, 1e6]
                                      own)
==============  ====================  ============================================  ===========

Every strength defaults to 0: a disruptor at strength 0 changes nothing (and draws nothing), so
its episodes equal the bare env's bit for bit. ``reset_params()`` restores the constructor's
strength; ``reset(options={"obsnoise": 0.1})`` sets it for the episode. A strength is a number
(``None`` is refused), each disruptor wraps a stack once, and a refused ``set_params`` or
``reset`` changes nothing.

Randomness: each disruptor has its own generator, spawned at every ``reset`` from the seed
sequence of the env's ``np_random`` (which ``reset(seed=...)`` seeds). So a seed fixes every
draw, disruptors never share a stream, and the env's own draws (initial states) are untouched.

Stacking: put disruptors *inside* the robust-RL wrappers (``DomainRandomization``,
``DynamicAdversarial``, ``ScheduledParams``, ``ContextObservation``), which can then span their
strengths. :func:`disrupt` stacks several in the canonical order (:data:`DISRUPTORS`: the
actuator's noise, then transmission delay; sensor noise, then sensor failures, then delay).
"""

from __future__ import annotations

import math
from collections import deque
from typing import Any, ClassVar

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from rrls.wrappers._checks import check_finite_action
from rrls.wrappers.access import ParamsForwarding

#: longest delay accepted (steps): a longer one is almost surely a unit mistake
MAX_DELAY = 10_000
#: largest standard deviation accepted: beyond it noise is no longer a disturbance but an
#: overflow (1e308 made observations infinite by step 3); 1e6 is ten times HumanoidStandup's
#: largest per-step reward
MAX_STD = 1e6
_UNSET: Any = object()


def spawn_generator(env: gym.Env) -> np.random.Generator:
    """A new generator for one disruptor and one episode, from ``env.np_random``'s seed sequence.

    Spawning does not advance the env's generator, so initial states stay those of the bare env.
    """
    rng = env.np_random
    seq = getattr(rng.bit_generator, "seed_seq", None)
    if isinstance(seq, np.random.SeedSequence):
        return np.random.default_rng(seq.spawn(1)[0])
    return np.random.default_rng(int(rng.integers(2**63)))  # pragma: no cover - other seedings


def _inner_params(env: gym.Env) -> dict[str, float]:
    """The parameters ``env``'s stack already has (none for an env without the interface)."""
    try:
        return dict(env.get_wrapper_attr("get_params")())
    except AttributeError:
        return {}


class Disruptor(ParamsForwarding, gym.utils.RecordConstructorArgs):
    """Base class: owns the parameter ``param`` (its strength) and a per-episode generator.

    Subclasses set ``param``, ``kind`` (``"probability"``, ``"std"`` or ``"steps"``) and
    implement the behaviour in ``step``/``reset`` hooks.
    """

    param: ClassVar[str]
    kind: ClassVar[str]

    def __init__(self, env: gym.Env, strength: float, **record: Any) -> None:
        gym.utils.RecordConstructorArgs.__init__(self, **record)
        super().__init__(env)
        inner = _inner_params(env)
        if self.param in inner:  # a second copy: set_params would reach only the outer one
            raise ValueError(
                f"{type(self).__name__}: the env already has the parameter {self.param!r} (it "
                f"is wrapped in {type(self).__name__} already); wrap each disruptor once"
            )
        problem = self.check_param(self.param, strength)
        if problem:
            raise ValueError(problem)
        self._initial = self._convert(strength)
        self.strength = self._initial
        self.rng = np.random.default_rng(0)  # replaced at every reset
        self._step = 0

    # -- the parameter ------------------------------------------------------------------------
    def own_params(self) -> dict[str, float]:
        """The parameters this wrapper owns (not forwarded down the stack)."""
        return {self.param: float(self.strength)}

    @classmethod
    def check_param(cls, name: str, value: Any) -> str | None:
        """Why ``value`` is not a valid strength, or None."""
        if isinstance(value, np.ndarray) and value.size == 1:
            value = value.item()
        if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
            return f"{name} must be a real number, got {value!r}"
        value = float(value)
        if not math.isfinite(value):
            return f"{name} must be finite, got {value!r}"
        if cls.kind == "probability" and not 0.0 <= value <= 1.0:
            return f"{name} is a probability and must be in [0, 1], got {value!r}"
        if cls.kind == "std" and not 0.0 <= value <= MAX_STD:
            return (
                f"{name} is a standard deviation and must be in [0, {MAX_STD:.0f}], got {value!r}"
            )
        if cls.kind == "steps" and not (value.is_integer() and 0 <= value <= MAX_DELAY):
            return (
                f"{name} is a number of steps and must be a whole number in [0, {MAX_DELAY}]"
                f", got {value!r}"
            )
        return None

    def _convert(self, value: Any) -> float | int:
        value = float(np.asarray(value).item())
        return int(value) if self.kind == "steps" else value

    def get_params(self, kinds: Any = None) -> dict[str, float]:
        """The inner env's parameters (``kinds`` forwarded) and this wrapper's own, always."""
        return {**ParamsForwarding.get_params(self, kinds), **self.own_params()}

    def set_params(self, **params: float) -> None:
        """Set this strength and forward the others; everything is validated before writing
        (``None`` is refused: it is not a strength)."""
        mine = params.pop(self.param, _UNSET)
        if mine is not _UNSET:
            problem = self.check_param(self.param, mine)
            if problem:
                raise ValueError(problem)
        if params:
            self.env.get_wrapper_attr("set_params")(**params)
        if mine is not _UNSET:
            self.strength = self._convert(mine)

    def reset_params(self) -> None:
        self.strength = self._initial
        self.env.get_wrapper_attr("reset_params")()

    # -- Gymnasium hooks ----------------------------------------------------------------------
    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        before = self.strength
        if options and self.param in options:
            options = dict(options)
            self.set_params(**{self.param: options.pop(self.param)})
        try:
            obs, info = self.env.reset(seed=seed, options=options or None)
        except BaseException:  # the inner env refused its options: a refused reset changes
            self.strength = before  # nothing, this strength included
            raise
        self.rng = spawn_generator(self.env)
        self._step = 0
        return self.on_reset(obs), info

    def on_reset(self, obs: Any) -> Any:
        """The first observation the agent sees."""
        return obs

    def step(self, action: Any):
        self._step += 1
        return self.env.step(action)


# -- observations ----------------------------------------------------------------------------
class ObservationNoise(Disruptor):
    """Add Gaussian noise of standard deviation ``std`` to every observation component.

    >>> import numpy as np
    >>> from rrls.envs import RobustHopper
    >>> from rrls.wrappers.disruptors import ObservationNoise
    >>> env = ObservationNoise(RobustHopper(), std=0.1)
    >>> noisy, _ = env.reset(seed=0)
    >>> clean, _ = RobustHopper().reset(seed=0)
    >>> bool(np.all(noisy != clean)), env.get_params()["obsnoise"]
    (True, 0.1)
    """

    param, kind = "obsnoise", "std"

    def __init__(self, env: gym.Env, std: float = 0.0) -> None:
        super().__init__(env, std, std=std)
        self.observation_space = env.observation_space

    def _noisy(self, obs: np.ndarray) -> np.ndarray:
        if self.strength == 0:
            return obs
        return (obs + self.rng.normal(0.0, self.strength, np.shape(obs))).astype(obs.dtype)

    def on_reset(self, obs: np.ndarray) -> np.ndarray:
        return self._noisy(obs)

    def step(self, action: Any):
        obs, reward, terminated, truncated, info = super().step(action)
        return self._noisy(obs), reward, terminated, truncated, info


class _SensorFailure(Disruptor):
    """Each component fails with probability ``probability`` at a step and stays failed for
    ``duration`` steps; a failed component reads :meth:`_failed_value`."""

    kind = "probability"

    def __init__(self, env: gym.Env, probability: float = 0.0, duration: int = 1) -> None:
        super().__init__(env, probability, probability=probability, duration=duration)
        if isinstance(duration, bool) or not isinstance(duration, (int, np.integer)):
            raise ValueError(f"duration must be a whole number of steps >= 1, got {duration!r}")
        if duration < 1:
            raise ValueError(f"duration must be a whole number of steps >= 1, got {duration!r}")
        self.duration = int(duration)
        self.observation_space = env.observation_space
        self._left = np.zeros(env.observation_space.shape, dtype=np.int64)
        self._last: np.ndarray | None = None

    def _failed_value(self, obs: np.ndarray) -> np.ndarray:
        raise NotImplementedError

    def _apply(self, obs: np.ndarray) -> np.ndarray:
        if self.strength > 0:
            new = self.rng.random(np.shape(obs)) < self.strength
            self._left = np.where(new & (self._left == 0), self.duration, self._left)
        failed = self._left > 0
        if failed.any():
            obs = np.where(failed, self._failed_value(obs), obs).astype(obs.dtype)
        self._left = np.maximum(self._left - 1, 0)
        self._last = obs
        return obs

    def on_reset(self, obs: np.ndarray) -> np.ndarray:
        self._left = np.zeros(np.shape(obs), dtype=np.int64)
        self._last = obs
        return self._apply(obs)

    def step(self, action: Any):
        obs, reward, terminated, truncated, info = super().step(action)
        return self._apply(obs), reward, terminated, truncated, info


class ObservationDropout(_SensorFailure):
    """Dropped sensors: a component reads 0 with probability ``probability`` at each step
    (and for the next ``duration - 1`` steps).

    >>> import numpy as np
    >>> from rrls.envs import RobustHopper
    >>> from rrls.wrappers.disruptors import ObservationDropout
    >>> env = ObservationDropout(RobustHopper(), probability=1.0)
    >>> obs, _ = env.reset(seed=0)
    >>> bool(np.all(obs == 0))
    True
    """

    param = "obsdropout"

    def _failed_value(self, obs: np.ndarray) -> np.ndarray:
        return np.zeros_like(obs)


class StuckSensors(_SensorFailure):
    """Stuck sensors: a component keeps its previous reading with probability ``probability``
    at each step (and for the next ``duration - 1`` steps).

    >>> import numpy as np
    >>> from rrls.envs import RobustHopper
    >>> from rrls.wrappers.disruptors import StuckSensors
    >>> env = StuckSensors(RobustHopper(), probability=1.0)
    >>> first, _ = env.reset(seed=0)
    >>> obs, *_ = env.step(np.ones(3))
    >>> bool(np.array_equal(obs, first))
    True
    """

    param = "obsstuck"

    def _failed_value(self, obs: np.ndarray) -> np.ndarray:
        return self._last if self._last is not None else obs


class ObservationDelay(Disruptor):
    """The agent sees the observation of ``steps`` steps ago (the reset observation until then).

    If the delay grows within an episode (a schedule or an adversary over ``obsdelay``), the
    oldest observation kept is shown until enough have arrived.

    >>> import numpy as np
    >>> from rrls.envs import RobustHopper
    >>> from rrls.wrappers.disruptors import ObservationDelay
    >>> env = ObservationDelay(RobustHopper(), steps=2)
    >>> first, _ = env.reset(seed=0)
    >>> seen = [env.step(np.ones(3))[0] for _ in range(3)]
    >>> [bool(np.array_equal(o, first)) for o in seen]
    [True, True, False]
    """

    param, kind = "obsdelay", "steps"

    def __init__(self, env: gym.Env, steps: int = 0) -> None:
        super().__init__(env, steps, steps=steps)
        self.observation_space = env.observation_space
        self._history: deque[np.ndarray] = deque()

    def _delayed(self, obs: np.ndarray) -> np.ndarray:
        history = self._history
        history.append(obs)
        while len(history) > self.strength + 1:
            history.popleft()
        return history[0]

    def on_reset(self, obs: np.ndarray) -> np.ndarray:
        self._history = deque([obs] * int(self.strength))
        return self._delayed(obs)

    def step(self, action: Any):
        obs, reward, terminated, truncated, info = super().step(action)
        return self._delayed(obs), reward, terminated, truncated, info


# -- actions ---------------------------------------------------------------------------------
class _ActionDisruptor(Disruptor):
    def __init__(self, env: gym.Env, strength: float, **record: Any) -> None:
        if not isinstance(env.action_space, spaces.Box):
            raise TypeError(
                f"{type(self).__name__} needs a Box action space, got {env.action_space}"
            )
        super().__init__(env, strength, **record)
        self.action_space = env.action_space

    def _checked(self, action: Any) -> np.ndarray:
        self._step += 1
        check_finite_action(action, self._step)
        arr = np.asarray(action)  # its own dtype: at strength 0 the env gets exactly it
        if arr.shape != self.action_space.shape:
            raise ValueError(f"action must have shape {self.action_space.shape}, got {arr.shape}")
        return arr


class ActionNoise(_ActionDisruptor):
    """Execute the action plus Gaussian noise of standard deviation ``std``, clipped to the
    action bounds. ``info["executed_action"]`` holds what the env executed.

    >>> import numpy as np
    >>> from rrls.envs import RobustHopper
    >>> from rrls.wrappers.disruptors import ActionNoise
    >>> env = ActionNoise(RobustHopper(), std=0.5)
    >>> _ = env.reset(seed=0)
    >>> *_, info = env.step(np.zeros(3))
    >>> bool(np.any(info["executed_action"] != 0))
    True
    """

    param, kind = "actionnoise", "std"

    def __init__(self, env: gym.Env, std: float = 0.0) -> None:
        super().__init__(env, std, std=std)

    def step(self, action: Any):
        arr = self._checked(action)
        if self.strength > 0:
            arr = arr.astype(np.result_type(arr.dtype, np.float32))
            noisy = arr + self.rng.normal(0.0, self.strength, arr.shape)
            arr = np.clip(noisy, self.action_space.low, self.action_space.high).astype(arr.dtype)
        obs, reward, terminated, truncated, info = self.env.step(arr)
        info["executed_action"] = arr
        return obs, reward, terminated, truncated, info


class ActionDelay(_ActionDisruptor):
    """Execute the action given ``steps`` steps ago; the episode's first action until then (it
    is executed ``steps + 1`` times), as realworldrl_suite's delay buffer, which starts full of
    the first item (``delayed_buffer_item``). ``info["executed_action"]`` holds what the env
    executed. If the delay grows within an episode, the oldest action kept is executed until
    enough have arrived.

    >>> import numpy as np
    >>> from rrls.envs import RobustHopper
    >>> from rrls.wrappers.disruptors import ActionDelay
    >>> env = ActionDelay(RobustHopper(), steps=1)
    >>> _ = env.reset(seed=0)
    >>> [float(env.step(np.full(3, a))[-1]["executed_action"][0]) for a in (0.5, -0.5, 0.1)]
    [0.5, 0.5, -0.5]
    """

    param, kind = "actiondelay", "steps"

    def __init__(self, env: gym.Env, steps: int = 0) -> None:
        super().__init__(env, steps, steps=steps)
        self._pending: deque[np.ndarray] = deque()

    def on_reset(self, obs: Any) -> Any:
        self._pending = deque()
        return obs

    def step(self, action: Any):
        pending = self._pending
        arr = self._checked(action)
        if self._step == 1:  # the first action stands in for the ones before the episode
            pending.extend([arr] * int(self.strength))
        pending.append(arr)
        while len(pending) > self.strength + 1:
            pending.popleft()
        executed = pending[0]
        obs, reward, terminated, truncated, info = self.env.step(executed)
        info["executed_action"] = executed
        return obs, reward, terminated, truncated, info


# -- rewards ---------------------------------------------------------------------------------
class RewardNoise(Disruptor):
    """Add Gaussian noise of standard deviation ``std`` to the reward the agent receives;
    ``info["true_reward"]`` keeps the env's. rrls's own: realworldrl_suite has no reward noise.

    >>> import numpy as np
    >>> from rrls.envs import RobustHopper
    >>> from rrls.wrappers.disruptors import RewardNoise
    >>> env = RewardNoise(RobustHopper(), std=1.0)
    >>> _ = env.reset(seed=0)
    >>> _, reward, *_, info = env.step(np.zeros(3))
    >>> bool(reward != info["true_reward"])
    True
    """

    param, kind = "rewardnoise", "std"

    def __init__(self, env: gym.Env, std: float = 0.0) -> None:
        super().__init__(env, std, std=std)

    def step(self, action: Any):
        obs, reward, terminated, truncated, info = super().step(action)
        info["true_reward"] = reward
        if self.strength > 0:
            reward = float(reward + self.rng.normal(0.0, self.strength))
        return obs, reward, terminated, truncated, info


#: every disruptor by the parameter it adds, innermost first: the order :func:`disrupt` stacks
DISRUPTORS: dict[str, type[Disruptor]] = {
    "actionnoise": ActionNoise,
    "actiondelay": ActionDelay,
    "obsnoise": ObservationNoise,
    "obsstuck": StuckSensors,
    "obsdropout": ObservationDropout,
    "obsdelay": ObservationDelay,
    "rewardnoise": RewardNoise,
}


def disrupt(env: gym.Env, **strengths: float) -> gym.Env:
    """Wrap ``env`` in the disruptors named by ``strengths``, in the canonical order.

    >>> from rrls.envs import RobustHopper
    >>> from rrls.wrappers.disruptors import disrupt
    >>> env = disrupt(RobustHopper(), obsnoise=0.05, actiondelay=1)
    >>> {k: v for k, v in env.get_params().items() if k in ("obsnoise", "actiondelay")}
    {'actiondelay': 1.0, 'obsnoise': 0.05}
    """
    unknown = [n for n in strengths if n not in DISRUPTORS]
    if unknown:
        raise ValueError(f"unknown disruptor(s) {unknown}; valid: {', '.join(DISRUPTORS)}")
    for name, cls in DISRUPTORS.items():
        if name in strengths:
            env = cls(env, strengths[name])
    return env


__all__ = [
    "ActionDelay",
    "ActionNoise",
    "disrupt",
    "Disruptor",
    "DISRUPTORS",
    "MAX_DELAY",
    "MAX_STD",
    "ObservationDelay",
    "ObservationDropout",
    "ObservationNoise",
    "RewardNoise",
    "spawn_generator",
    "StuckSensors",
]
