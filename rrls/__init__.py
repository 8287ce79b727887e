"""rrls — the Robust Reinforcement Learning Suite.

Robust MuJoCo tasks whose physics can be changed through ``set_params``/``get_params``, the
paper's uncertainty sets, robust-RL wrappers, and (in later modules) evaluation and baselines.

``import rrls`` is cheap: it registers the Gymnasium ids and builds no environment; the
submodules load on first use.

>>> import gymnasium as gym
>>> env = gym.make("rrls/robust-hopper-v0")
>>> env.set_params(torsomass=2.0)
>>> env.get_params()["torsomass"]
2.0

Through a wrapper that hides ``set_params`` (any Gymnasium wrapper): ``rrls.set_params(env,
torsomass=2.0)`` (:mod:`rrls.interface`). ``rrls.evaluation.evaluate(policy, "hopper")``
evaluates a policy's worst and average case.
"""

from __future__ import annotations

import importlib
from typing import Any

__version__ = "0.1.0"

_LAZY = {
    "envs": "rrls.envs",
    "wrappers": "rrls.wrappers",
    "uncertainty": "rrls.uncertainty",
    "UncertaintySet": "rrls.uncertainty",
    "Split": "rrls.uncertainty",
    "ModifiedParamsEnv": "rrls.interface",
    "set_params": "rrls.interface",
    "get_params": "rrls.interface",
    "get_uncertainty_set": "rrls.envs",
    "generate_evaluation_set": "rrls.evaluation",
    "evaluation": "rrls.evaluation",
    "evaluate": "rrls.evaluate",
    "register_task": "rrls.registry",
    "load_task_plugins": "rrls.registry",
    "TaskSpec": "rrls.registry",
    "Parameter": "rrls.params",
    "ParamSpec": "rrls.params",  # deprecated: Parameter's former name (warns)
}
#: lazy names kept for old code, left out of ``__all__`` (``import *`` would warn) and of
#: ``dir(rrls)`` (tools that read every listed name, pytest's fixture scan among them, would warn)
_DEPRECATED = ("ParamSpec",)


def make_wrapped_env(cls_env: Any, wrapper: Any, **kwargs: Any) -> Any:
    """``wrapper(env=cls_env(), **kwargs)``: the original code's helper (and entry point)."""
    return wrapper(env=cls_env(), **kwargs)


def __getattr__(name: str) -> Any:
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module 'rrls' has no attribute {name!r}")
    mod = importlib.import_module(module)
    value = mod if module.endswith(name) else getattr(mod, name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(n for n in [*globals(), *_LAZY] if n not in _DEPRECATED)


from rrls._registration import register_envs  # noqa: E402

register_envs()

# every public name once (UncertaintySet and get_uncertainty_set are also lazy names)
_EAGER = ["UncertaintySet", "__version__", "get_uncertainty_set", "make_wrapped_env"]
__all__ = [n for n in dict.fromkeys([*_EAGER, "register_envs", *_LAZY]) if n not in _DEPRECATED]
