"""Gymnasium registration of every rrls id (no environment is built here).

The ids of each task come from its declaration (:func:`rrls.gym_ids.task_ids`):
``rrls/robust-hopper-v0``, ``rrls/force-hopper-v0``, ``rrls/robust-hopper-adversarial-3d-v0``,
``rrls/robust-hopper-adversarial-forces-v0``, ``rrls/robust-hopper-domain-randomization-3d-v0``,
``rrls/probabilistic-action-robust-hopper-v0`` (and the original's un-namespaced
``probabilistic-action-robust-hopper-v0``). :func:`rrls.register_task` registers a new task's
ids itself; ``import rrls`` calls this for the built-in ones (so does Gymnasium's
``gym.make("rrls:rrls/...")``, which imports rrls).
"""

from __future__ import annotations

from rrls.gym_ids import NR_MDP_ALPHA, register_ids
from rrls.registry import MAX_EPISODE_STEPS
from rrls.tasks import TASKS


def register_envs() -> None:
    """Register the ids of every declared task with Gymnasium (idempotent, cheap)."""
    for task in TASKS.values():
        register_ids(task)


__all__ = ["MAX_EPISODE_STEPS", "NR_MDP_ALPHA", "register_envs"]
