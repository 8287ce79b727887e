"""The ``ModifiedParamsEnv`` protocol: what every rrls environment (and wrapper) offers."""

from __future__ import annotations

from typing import Any, Protocol, runtime_checkable

import gymnasium as gym


@runtime_checkable
class ModifiedParamsEnv(Protocol):
    """A Gymnasium env whose physical parameters can be read and written by name.

    ``set_params`` takes any subset of the names ``get_params`` returns; unknown names raise a
    ``ValueError`` listing the valid ones, non-finite or non-physical values are refused.
    rrls's envs also take ``get_params(kinds="all")`` (every parameter; without it, the original
    code's kinds); an env of this protocol need not.
    """

    action_space: gym.Space
    observation_space: gym.Space

    def set_params(self, **params: float) -> None: ...

    def get_params(self) -> dict[str, float]: ...

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None): ...

    def step(self, action: Any): ...


def all_params(env: Any) -> dict[str, float]:
    """Every parameter of ``env``'s stack: ``get_params(kinds="all")``, or ``get_params()`` of an
    env whose ``get_params`` takes no ``kinds`` (a user's own :class:`ModifiedParamsEnv`)."""
    get = env.get_wrapper_attr("get_params") if hasattr(env, "get_wrapper_attr") else env.get_params
    try:
        return get(kinds="all")
    except TypeError:
        return get()
