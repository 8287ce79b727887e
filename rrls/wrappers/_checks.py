"""Shared validation for the wrappers."""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from rrls.uncertainty import UncertaintySet


def check_names(env: gym.Env, box: UncertaintySet) -> None:
    """Refuse a set naming parameters that ``env`` does not have (listing the valid ones), or
    whose bounds are not physical values (a negative mass fails here, not episodes later)."""
    from rrls.params import check_bounds

    valid = env.get_wrapper_attr("get_params")()
    specs = getattr(env.unwrapped, "param_specs", ())
    aliases = {a for s in specs for a in s.aliases}
    unknown = [n for n in box.names if n not in valid and n not in aliases]
    if unknown:
        raise ValueError(f"unknown parameter(s) {unknown}; valid names: {', '.join(valid)}")
    check_bounds(specs, box)


def split_pair(action: Any, space: spaces.Tuple) -> tuple[np.ndarray, np.ndarray]:
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
            raise ValueError(f"{who} action must be finite, got {arr}")
        out.append(arr)
    return out[0], out[1]
