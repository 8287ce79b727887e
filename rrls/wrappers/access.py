"""Forwarding of the ``ModifiedParamsEnv`` interface through wrapper stacks."""

from __future__ import annotations

from typing import Any

import gymnasium as gym

from rrls.wrappers._checks import check_finite_action


class ParamsForwarding(gym.Wrapper):
    """A wrapper that keeps ``set_params``/``get_params``/``reset_params`` callable on itself.

    Gymnasium 1.x wrappers no longer forward unknown attributes, so each rrls wrapper derives
    from this one and forwards the interface to the innermost env that has it.
    """

    def set_params(self, **params: float) -> None:
        self.env.get_wrapper_attr("set_params")(**params)

    def get_params(self, kinds: Any = None) -> dict[str, float]:
        """The inner env's ``get_params`` (``kinds`` forwarded when given: see the envs')."""
        get = self.env.get_wrapper_attr("get_params")
        return get() if kinds is None else get(kinds=kinds)

    def reset_params(self) -> None:
        self.env.get_wrapper_attr("reset_params")()


class ParamsAccess(ParamsForwarding, gym.utils.RecordConstructorArgs):
    """Outermost wrapper of every registered rrls id: ``gym.make(...)`` has ``set_params``.

    It also refuses NaN/inf actions before they reach MuJoCo (a one-line error naming the step).

    >>> import gymnasium as gym
    >>> env = gym.make("rrls/robust-walker-v0")
    >>> env.set_params(worldfriction=0.3)
    >>> env.get_params()["worldfriction"]
    0.3
    """

    def __init__(self, env: gym.Env) -> None:
        gym.utils.RecordConstructorArgs.__init__(self)
        super().__init__(env)
        self._step = 0

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        self._step = 0
        return self.env.reset(seed=seed, options=options)

    def step(self, action: Any):
        self._step += 1
        check_finite_action(action, self._step)
        return self.env.step(action)


__all__ = ["ParamsAccess", "ParamsForwarding"]
