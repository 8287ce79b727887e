"""Forwarding of the ``ModifiedParamsEnv`` interface through wrapper stacks."""

from __future__ import annotations

import gymnasium as gym


class ParamsForwarding(gym.Wrapper):
    """A wrapper that keeps ``set_params``/``get_params``/``reset_params`` callable on itself.

    Gymnasium 1.x wrappers no longer forward unknown attributes, so each rrls wrapper derives
    from this one and forwards the interface to the innermost env that has it.
    """

    def set_params(self, **params: float) -> None:
        self.env.get_wrapper_attr("set_params")(**params)

    def get_params(self) -> dict[str, float]:
        return self.env.get_wrapper_attr("get_params")()

    def reset_params(self) -> None:
        self.env.get_wrapper_attr("reset_params")()


class ParamsAccess(ParamsForwarding, gym.utils.RecordConstructorArgs):
    """Outermost wrapper of every registered rrls id: ``gym.make(...)`` has ``set_params``.

    >>> import gymnasium as gym
    >>> env = gym.make("rrls/robust-walker-v0")
    >>> env.set_params(worldfriction=0.3)
    >>> env.get_params()["worldfriction"]
    0.3
    """

    def __init__(self, env: gym.Env) -> None:
        gym.utils.RecordConstructorArgs.__init__(self)
        super().__init__(env)
