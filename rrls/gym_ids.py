"""A task's Gymnasium ids: which ids a task declaration gives (:func:`task_ids`) and their
registration with Gymnasium (:func:`register_ids`), the one place that knows the id scheme::

    rrls/robust-<key>-v0, rrls/force-<key>-v0, rrls/robust-<key>-adversarial-<set>-v0,
    rrls/robust-<key>-adversarial-forces-v0, rrls/robust-<key>-domain-randomization-<set>-v0,
    rrls/probabilistic-action-robust-<key>-v0 (and the original's un-namespaced spelling)

``spec`` is a task declaration (``rrls.registry.TaskSpec``); nothing here builds an env.
"""

from __future__ import annotations

from typing import Any

from gymnasium.envs.registration import WrapperSpec, register, registry

#: the action-robust game's mixing probability of the registered ids (NR-MDP's paper value)
NR_MDP_ALPHA = 0.1

_ACCESS = WrapperSpec("ParamsAccess", "rrls.wrappers.access:ParamsAccess", {})


def _wrapper(name: str, module: str, **kwargs: Any) -> WrapperSpec:
    return WrapperSpec(name, f"rrls.wrappers.{module}:{name}", kwargs)


def task_ids(spec: Any) -> dict[str, tuple[str, WrapperSpec | None]]:
    """Every Gymnasium id of the task -> (entry point, game wrapper or None)."""
    key = spec.key
    robust, force = f"rrls.envs:Robust{spec.name}", f"rrls.envs:Force{spec.name}"
    ids: dict[str, tuple[str, WrapperSpec | None]] = {f"rrls/robust-{key}-v0": (robust, None)}
    if spec.forces:
        ids[f"rrls/force-{key}-v0"] = (force, None)
    for set_name, family in spec.families.items():
        bounds = {k: [lo, hi] for k, (lo, hi) in spec.sets[set_name].items()}
        adversary = _wrapper("DynamicAdversarial", "adversarial", params_bound=bounds)
        if family == "force":
            ids[f"rrls/robust-{key}-adversarial-forces-v0"] = (force, adversary)
            continue
        dr = _wrapper("DomainRandomization", "domain_randomization", params_bound=bounds)
        ids[f"rrls/robust-{key}-adversarial-{set_name}-v0"] = (robust, adversary)
        ids[f"rrls/robust-{key}-domain-randomization-{set_name}-v0"] = (robust, dr)
    par = _wrapper("ProbabilisticActionRobust", "action_robust", alpha=NR_MDP_ALPHA)
    ids[f"rrls/probabilistic-action-robust-{key}-v0"] = (robust, par)
    ids[f"probabilistic-action-robust-{key}-v0"] = (robust, par)  # the original's spelling
    return ids


def register_ids(spec: Any, replace: bool = False) -> None:
    """Register the task's Gymnasium ids (idempotent; ``replace``: overwrite existing ones).

    Each id is the env class with Gymnasium's usual wrappers (the task's time limit), then the
    game wrapper as a Gymnasium ``additional_wrappers`` spec (so ``env.spec`` round-trips), then
    :class:`rrls.wrappers.ParamsAccess` outermost, so ``set_params``/``get_params`` are callable
    on what ``gym.make`` returns, as in the original code.
    """
    for env_id, (entry_point, game) in task_ids(spec).items():
        if env_id in registry:
            if not replace:
                continue
            del registry[env_id]
        register(
            id=env_id,
            entry_point=entry_point,
            max_episode_steps=spec.max_episode_steps,
            additional_wrappers=((game,) if game else ()) + (_ACCESS,),
        )


def unregister_ids(spec: Any) -> None:
    """Forget the task's Gymnasium ids."""
    for env_id in task_ids(spec):
        registry.pop(env_id, None)


__all__ = ["NR_MDP_ALPHA", "register_ids", "task_ids", "unregister_ids"]
