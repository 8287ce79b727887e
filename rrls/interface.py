"""The ``ModifiedParamsEnv`` protocol: what every rrls environment (and wrapper) offers.

Through a wrapper that is not rrls's own (``gymnasium.wrappers.RecordEpisodeStatistics``,
``TimeLimit``...) ``env.set_params`` is hidden: Gymnasium wrappers no longer forward unknown
attributes. Reach it through any stack with :func:`set_params` / :func:`get_params` below, or
Gymnasium's own ``env.get_wrapper_attr("set_params")(...)`` or ``env.unwrapped.set_params(...)``
(the last skips rrls wrappers that intercept the call, such as ``ScheduledParams``).

>>> import gymnasium as gym
>>> from rrls.interface import get_params, set_params
>>> env = gym.wrappers.RecordEpisodeStatistics(gym.make("rrls/robust-hopper-v0"))
>>> set_params(env, torsomass=2.0)
>>> get_params(env)["torsomass"]
2.0
"""

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


def set_params(env: Any, **params: float) -> None:
    """``set_params`` of the outermost layer of ``env``'s wrapper stack that has it, whatever
    wraps it (``get_wrapper_attr``); a one-line ``TypeError`` if none has."""
    _method(env, "set_params")(**params)


def get_params(env: Any, **kwargs: Any) -> dict[str, float]:
    """``get_params`` of the outermost layer of ``env``'s stack that has it (see
    :func:`set_params`); ``kwargs`` are passed on (rrls's envs take ``kinds="all"``)."""
    return _method(env, "get_params")(**kwargs)


def _method(env: Any, name: str) -> Any:
    try:
        if hasattr(env, "get_wrapper_attr"):
            return env.get_wrapper_attr(name)
        return getattr(env, name)
    except AttributeError:
        raise TypeError(
            f"{type(env).__name__} has no {name} anywhere in its wrapper stack (not an rrls env?)"
        ) from None


def is_modified_params_env(obj: Any) -> bool:
    """Whether ``obj`` is a Gymnasium env with callable ``set_params`` and ``get_params``."""
    methods = all(callable(getattr(obj, m, None)) for m in ("set_params", "get_params"))
    return methods and isinstance(obj, gym.Env)


def all_params(env: Any) -> dict[str, float]:
    """Every parameter of ``env``'s stack: ``get_params(kinds="all")``, or ``get_params()`` of an
    env whose ``get_params`` takes no ``kinds`` (a user's own :class:`ModifiedParamsEnv`)."""
    get = env.get_wrapper_attr("get_params") if hasattr(env, "get_wrapper_attr") else env.get_params
    try:
        return get(kinds="all")
    except TypeError:
        return get()


__all__ = ["ModifiedParamsEnv", "all_params", "get_params", "is_modified_params_env", "set_params"]
