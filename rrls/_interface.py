"""The original RRLS module path ``rrls._interface``: code written for it imports unchanged."""

from __future__ import annotations

from typing import Any

import gymnasium as gym

from rrls.interface import ModifiedParamsEnv

#: the original's name of the protocol without the ``gym.Env`` part
ModifiedParams = ModifiedParamsEnv


def check_protocol_modified_params_env(obj: Any) -> bool:
    """Whether ``obj`` is a Gymnasium env with callable ``set_params`` and ``get_params``."""
    methods = all(callable(getattr(obj, m, None)) for m in ("set_params", "get_params"))
    return methods and isinstance(obj, gym.Env)


__all__ = ["ModifiedParams", "ModifiedParamsEnv", "check_protocol_modified_params_env"]
