"""One place a policy is made ready for an evaluation: adapted (``as_policy``), checked against
the task's spaces and training task, probed for batch invariance and fingerprinted — once."""

from __future__ import annotations

import warnings
from collections.abc import Callable
from typing import Any, NamedTuple

import numpy as np

from rrls.evaluation.lanes import PolicyError, make_rollout_envs
from rrls.evaluation.policies import as_policy, is_batch_invariant, policy_fingerprint

__all__ = ["PreparedPolicy", "policy_record", "prepare_policy"]


class PreparedPolicy(NamedTuple):
    policy: Callable[[np.ndarray], Any]  # the adapted policy the engine calls
    obs_dim: int
    fingerprint: str  # its actions on fixed probes, hashed: a resume with another is refused


def prepare_policy(policy: Any, spec: Any, stacklevel: int = 3) -> PreparedPolicy:
    """Adapt ``policy`` and check it against ``spec``'s task (a policy trained on another task,
    wrong shapes, non-numbers: one-line errors before any episode); warn once if its actions
    depend on the batch (then results may differ in the last bits from a one-episode loop)."""
    policy = as_policy(policy)
    trained_on = (getattr(policy, "metadata", None) or {}).get("task")
    if trained_on is not None and trained_on != spec.task:
        raise ValueError(f"the policy was trained on {trained_on!r}, not on task {spec.task!r}")
    obs_dim, act_dim = _dims(spec)
    _check_policy(policy, obs_dim, act_dim)
    if not is_batch_invariant(policy, obs_dim):
        warnings.warn(
            "the policy's actions depend on the batch size (BLAS kernels differ), so results may "
            "differ in the last bits from a one-episode-at-a-time loop; wrap it in "
            "rrls.evaluation.BatchInvariant(policy) for exact equality",
            stacklevel=stacklevel,
        )
    return PreparedPolicy(policy, obs_dim, policy_fingerprint(policy, obs_dim))


def policy_record(policy: Any) -> dict[str, Any]:
    """What ``summary.json`` says of the policy: its algorithm, training seed and run directory."""
    meta = getattr(policy, "metadata", None) or {}
    record = {
        "policy_algorithm": meta.get("algorithm"),
        "policy_seed": meta.get("seed"),
        "policy_run_dir": meta.get("run_dir"),
        "policy_path": meta.get("path"),
    }
    return {k: v for k, v in record.items() if v is not None}


def _dims(spec: Any) -> tuple[int, int]:
    env = make_rollout_envs(spec, 1)[0]
    return env.observation_space.shape[0], env.action_space.shape[0]


def _check_policy(policy: Callable, obs_dim: int, act_dim: int) -> None:
    """Fail before any rollout if the policy cannot map observations to actions."""
    try:
        out = np.asarray(policy(np.zeros((2, obs_dim))))
    except Exception as err:
        raise PolicyError(
            f"calling the policy on a batch of observations of shape (2, {obs_dim}) failed: {err}"
        ) from err
    if out.dtype.kind not in "biuf":
        raise PolicyError(f"the policy returned {out.dtype} values; actions must be real numbers")
    if out.shape != (2, act_dim):
        raise PolicyError(
            f"the policy maps observations (2, {obs_dim}) to shape {out.shape}; expected "
            f"(2, {act_dim}) for this task"
        )
