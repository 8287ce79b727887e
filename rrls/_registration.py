"""Gymnasium registration of every rrls id, as data (no environment is built here).

Ids follow the original RRLS code: ``rrls/robust-hopper-v0``, ``rrls/force-hopper-v0``,
``rrls/robust-hopper-adversarial-3d-v0``, ``rrls/robust-hopper-adversarial-forces-v0``,
``rrls/robust-hopper-domain-randomization-3d-v0``, ``rrls/probabilistic-action-robust-hopper-v0``
(and the original's un-namespaced ``probabilistic-action-robust-hopper-v0``).

Each id is the robust (or force) env class with Gymnasium's usual wrappers (time limit of 1000
steps), then the game wrapper as a Gymnasium ``additional_wrappers`` spec (so ``env.spec``
round-trips), then :class:`rrls.wrappers.ParamsAccess` outermost, so the object ``gym.make``
returns has ``set_params``/``get_params`` callable directly, as in the original.
"""

from __future__ import annotations

from typing import Any

from gymnasium.envs.registration import WrapperSpec, register, registry

from rrls.tasks import TASKS, TaskSpec

MAX_EPISODE_STEPS = 1000
NR_MDP_ALPHA = 0.1

_ACCESS = WrapperSpec("ParamsAccess", "rrls.wrappers.access:ParamsAccess", {})


def _register(env_id: str, entry_point: str, game: WrapperSpec | None = None) -> None:
    """The env class, Gymnasium's usual wrappers, then ``game`` (if any) and ``ParamsAccess``."""
    if env_id in registry:
        return
    register(
        id=env_id,
        entry_point=entry_point,
        max_episode_steps=MAX_EPISODE_STEPS,
        additional_wrappers=((game,) if game else ()) + (_ACCESS,),
    )


def _wrapper(name: str, module: str, **kwargs: Any) -> WrapperSpec:
    return WrapperSpec(name, f"rrls.wrappers.{module}:{name}", kwargs)


def _bounds(task: TaskSpec, name: str) -> dict[str, list[float]]:
    return {k: [lo, hi] for k, (lo, hi) in task.sets[name].items()}


def register_envs() -> None:
    """Register all rrls ids with Gymnasium (idempotent, cheap)."""
    for key, task in TASKS.items():
        robust, force = f"rrls.envs:Robust{task.name}", f"rrls.envs:Force{task.name}"
        _register(f"rrls/robust-{key}-v0", robust)
        _register(f"rrls/force-{key}-v0", force)
        for name, family in task.families.items():
            bounds = _bounds(task, name)
            if family == "force":
                _register(
                    f"rrls/robust-{key}-adversarial-forces-v0",
                    force,
                    _wrapper("DynamicAdversarial", "adversarial", params_bound=bounds),
                )
                continue
            _register(
                f"rrls/robust-{key}-adversarial-{name}-v0",
                robust,
                _wrapper("DynamicAdversarial", "adversarial", params_bound=bounds),
            )
            _register(
                f"rrls/robust-{key}-domain-randomization-{name}-v0",
                robust,
                _wrapper("DomainRandomization", "domain_randomization", params_bound=bounds),
            )
        par = _wrapper("ProbabilisticActionRobust", "action_robust", alpha=NR_MDP_ALPHA)
        _register(f"rrls/probabilistic-action-robust-{key}-v0", robust, par)
        _register(f"probabilistic-action-robust-{key}-v0", robust, par)
