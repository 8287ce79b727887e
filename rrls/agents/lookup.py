"""How an algorithm is found by name and loaded: its ``Learner`` class, its ``Config`` dataclass
of hyper-parameters and its ``make_env(task, uncertainty, config)``.

Built-in ones and declared plug-ins are rows of ``rrls.algorithms.ALGORITHMS``; an installed
entry point (group ``rrls.algorithms``, value ``package.module:Learner``) or a name given as
``package.module:Learner`` works too. The ``Config`` and ``make_env`` come from the class if it
has them, else from its module, else TD3's.
"""

from __future__ import annotations

import dataclasses
import importlib
from typing import Any, NamedTuple

from rrls.agents.algos import td3
from rrls.algorithms import algorithm_info, built_in, plugin_entry_points

__all__ = [
    "LEARNER_METHODS",
    "Algorithm",
    "ResolvedRun",
    "algorithm",
    "hyperparameters",
    "resolve_run",
    "warm_up",
]

#: what the training loop calls on a learner (``rrls.agents.learner``)
LEARNER_METHODS = ("act", "observe", "update", "state_dict", "load_state_dict", "export")


class Algorithm(NamedTuple):
    name: str
    Config: type
    make_env: Any
    Learner: type


#: algorithms loaded and checked in this process, by (name, learner): each once
_LOADED: dict[tuple[str, str], Algorithm] = {}


def algorithm(name: str) -> Algorithm:
    """The algorithm ``name``: built-in, an entry point, or ``package.module:Learner``; loaded
    and checked once per process (a failure is not remembered: it is raised again)."""
    info = algorithm_info(name)
    if info is None:
        valid = ", ".join(dict.fromkeys([*built_in(), *plugin_entry_points()]))
        raise ValueError(f"unknown algorithm {name!r}; valid: {valid}, or package.module:Learner")
    key = (name, info.learner)
    if key not in _LOADED:
        _LOADED[key] = _load(name, info.learner)
    return _LOADED[key]


def _load(name: str, target: str) -> Algorithm:
    module_name, _, attr = target.partition(":")
    try:
        module = importlib.import_module(module_name)
        learner = getattr(module, attr or "Learner")
    except Exception as err:  # noqa: BLE001 - a plug-in's import may raise anything: one line
        first = (str(err).strip().splitlines() or [""])[0]
        raise ValueError(
            f"algorithm {name!r}: cannot load {target} ({type(err).__name__}: {first})"
        ) from None
    config = getattr(learner, "Config", None) or getattr(module, "Config", td3.Config)
    make_env = getattr(learner, "make_env", None) or getattr(module, "make_env", td3.make_env)
    _check_learner(name, target, learner, config, make_env)
    return Algorithm(name, config, make_env, learner)


def _check_learner(name: str, target: str, learner: Any, config: Any, make_env: Any) -> None:
    """Refuse what cannot be a learner (``json:loads``, a class without the protocol) in one
    line, before the loop calls it with arguments it does not take."""
    missing = [m for m in LEARNER_METHODS if not callable(getattr(learner, m, None))]
    if not isinstance(learner, type) or missing:
        what = (
            f"lacks {', '.join(missing)}"
            if isinstance(learner, type)
            else f"is a {type(learner).__name__}"
        )
        raise ValueError(
            f"algorithm {name!r}: {target} {what}: not a learner (a class with the methods "
            f"{', '.join(LEARNER_METHODS)}; docs/algorithms.md)"
        )
    if not (isinstance(config, type) and dataclasses.is_dataclass(config)):
        raise ValueError(
            f"algorithm {name!r}: its Config must be a dataclass of hyper-parameters, got "
            f"{config!r}"
        )
    if not callable(make_env):
        raise ValueError(f"algorithm {name!r}: its make_env must be callable, got {make_env!r}")


class ResolvedRun(NamedTuple):
    """One run as the training loop takes it, resolved once: its settings (a ``TrainConfig``),
    its algorithm (the row's loaded learner, ``Config`` class and env factory) and its
    hyper-parameters (that ``Config`` with the run's overrides)."""

    settings: Any
    algorithm: Algorithm
    hyper: Any


def resolve_run(config: Any) -> ResolvedRun:
    """``config`` resolved: its algorithm loaded (once per process) and its ``Config`` built and
    validated (an unknown hyper-parameter: one line naming the valid ones)."""
    return ResolvedRun(config, algorithm(config.algo), hyperparameters(config))


def hyperparameters(config: Any) -> Any:
    """The algorithm's ``Config`` with the run's overrides (``config.hyper``), validated; or
    ``config.hyper`` itself when it is that ``Config`` already (``TrainConfig(algo="td3",
    hyper=td3.Config(tau=0.01))``: typed, checked where it is written)."""
    cls = algorithm(config.algo).Config
    if dataclasses.is_dataclass(config.hyper) and not isinstance(config.hyper, type):
        if type(config.hyper) is not cls:
            raise ValueError(
                f"hyper is a {type(config.hyper).__module__}.{type(config.hyper).__qualname__}; "
                f"{config.algo} takes its {cls.__module__}.{cls.__qualname__} (or a dict of "
                "that Config's fields to override)"
            )
        return config.hyper
    valid = set(cls.__dataclass_fields__)
    unknown = sorted(set(config.hyper) - valid)
    if unknown:
        raise ValueError(
            f"{config.algo} has no hyper-parameter {', '.join(map(repr, unknown))}; "
            f"valid: {', '.join(sorted(valid))}"
        )
    return cls(**config.hyper)


def warm_up(hyper: Any) -> int:
    """The run's uniformly random steps before learning starts: its ``Config``'s
    ``learning_starts`` (the built-ins' default is their row's, ``rrls.algorithms.warmup``); a
    plug-in whose ``Config`` declares none gets none (it acts from its first step). The one rule
    the CPU loop and the twin's both read."""
    return int(getattr(hyper, "learning_starts", 0))
