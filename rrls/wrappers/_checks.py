"""Shared validation for the wrappers."""

from __future__ import annotations

import math
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from rrls.interface import all_params
from rrls.uncertainty import UncertaintySet


def check_names(env: gym.Env, box: UncertaintySet) -> None:
    """Refuse a set naming parameters that ``env`` does not have (listing the valid ones), or
    whose bounds are not physical values (a negative mass fails here, not episodes later).

    Names may also be the parameters of wrappers in the stack (disruptor strengths, schedule
    fields): their bounds are checked by the wrapper that owns them (``check_param``).
    """
    from rrls.params import check_bounds

    valid = all_params(env)
    specs = getattr(env.unwrapped, "param_specs", ())
    aliases = {a for s in specs for a in s.aliases}
    unknown = [n for n in box.names if n not in valid and n not in aliases]
    if unknown:
        raise ValueError(f"unknown parameter(s) {unknown}; valid names: {', '.join(valid)}")
    check_bounds(specs, box)
    physical = {s.name for s in specs} | aliases
    for name, lo, hi in zip(box.names, box.low, box.high):
        if name in physical:
            continue
        for bound in (float(lo), float(hi)):
            problem = wrapper_param_problem(env, name, bound)
            if problem:
                raise ValueError(f"uncertainty set bound out of range: {problem}")


def read_point(env: gym.Env, box: UncertaintySet) -> np.ndarray:
    """The current values of ``box``'s parameters in ``env`` (aliases read their parameter)."""
    params = all_params(env)
    specs = getattr(env.unwrapped, "param_specs", ())
    canonical = {a: s.name for s in specs for a in s.aliases}
    return np.array([params[canonical.get(n, n)] for n in box.names], dtype=np.float64)


def wrapper_param_problem(env: gym.Env, name: str, value: float) -> str | None:
    """Why ``value`` is not acceptable for the wrapper parameter ``name`` (None: it is)."""
    while isinstance(env, gym.Wrapper):
        owned = getattr(env, "own_params", None)
        if owned is not None and name in owned():
            return env.check_param(name, value)
        env = env.env
    return None


def refuse_empty(box: UncertaintySet, who: str, env: gym.Env) -> None:
    """An empty set would make ``who`` a silent no-op: refuse it, naming the valid parameters."""
    if box.dim == 0:
        valid = ", ".join(all_params(env))
        raise ValueError(
            f"{who} needs at least one parameter, got an empty uncertainty set; valid names: "
            f"{valid}"
        )


def check_finite_action(action: Any, step: int, who: str = "action") -> None:
    """Refuse a NaN/inf action before it reaches MuJoCo, naming the episode's step (from 1)."""
    if type(action) is np.ndarray and action.dtype.kind == "f" and action.ndim == 1:
        # the common case, cheaply (a Python sum of the list: ~0.5 us, half a numpy dot's): a
        # NaN/inf makes the sum non-finite (an overflow of huge finite values too, which the
        # exact check below then lets through)
        if math.isfinite(sum(action.tolist())):
            return
    if isinstance(action, (tuple, list)) and action and not np.isscalar(action[0]):
        for part in action:
            check_finite_action(part, step, who)
        return
    try:
        arr = np.asarray(action, dtype=np.float64)
    except (TypeError, ValueError):
        return  # not numbers: the env's own checks report it
    if not np.isfinite(arr).all():
        raise ValueError(
            f"{who} at step {step} of the episode is not finite: {arr.tolist()}; "
            "actions must be finite numbers"
        )


def split_pair(
    action: Any, space: spaces.Tuple, step: int | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """``(agent, adversary)`` arrays from a 2-tuple action, with a clear error on bad shapes."""
    if not isinstance(action, (tuple, list)) or len(action) != 2:
        raise ValueError(
            "this env takes a pair (agent_action, adversary_action); "
            f"got {type(action).__name__} {np.shape(action) if hasattr(action, '__len__') else ''}"
        )
    out = []
    for who, act, sub in zip(("agent", "adversary"), action, space.spaces):
        arr = np.asarray(act, dtype=sub.dtype)
        if arr.shape != sub.shape:
            raise ValueError(f"{who} action must have shape {sub.shape}, got {arr.shape}")
        if not np.isfinite(arr).all():
            where = f" at step {step} of the episode" if step is not None else ""
            raise ValueError(f"{who} action{where} must be finite, got {arr.tolist()}")
        out.append(arr)
    return out[0], out[1]
