"""One place a policy is made ready for an evaluation: adapted (``as_policy``), checked against
the task's spaces and training task, probed for batch invariance and fingerprinted — once.

``prepare(policy, task, protocol)`` does it at the door and returns a :class:`PreparedPolicy`
that ``evaluate``, ``evaluate_dynamic``, ``search_worst_case`` and the benchmark's stages take
as it is (a submitted policy is prepared once, then evaluated on the mesh and against its
adversary without being adapted, checked or probed again).

>>> import numpy as np
>>> from rrls.evaluation import Protocol, evaluate, prepare
>>> ready = prepare(lambda obs: np.zeros((len(obs), 1)), "invertedpendulum", Protocol("1d"))
>>> ready.obs_dim, ready.act_dim, len(ready.fingerprint)
(4, 1, 16)
>>> evaluate(ready, "invertedpendulum", "1d", mesh=2, episodes=1, workers=1).worst_case > 0
True
"""

from __future__ import annotations

import hashlib
import warnings
from collections.abc import Callable
from typing import Any

import numpy as np

from rrls.evaluation.lanes import PolicyError, Rollouts, make_rollout_envs
from rrls.evaluation.policies import as_policy

__all__ = [
    "PreparedPolicy",
    "is_batch_invariant",
    "policy_fingerprint",
    "policy_record",
    "prepare",
    "prepare_policy",
]


class PreparedPolicy:
    """A policy adapted, checked, probed and fingerprinted for one task's observations: the
    engine calls it as the policy itself; ``metadata`` is the policy's (its view, its record)."""

    def __init__(
        self,
        policy: Callable[[np.ndarray], Any],
        task: str,
        obs_dim: int,
        act_dim: int,
        fingerprint: str,
    ) -> None:
        self.policy, self.task = policy, task
        self.obs_dim, self.act_dim = obs_dim, act_dim
        self.fingerprint = fingerprint  # actions on fixed probes, hashed: guards resumes
        self.metadata = getattr(policy, "metadata", None)

    def __call__(self, obs: np.ndarray) -> Any:
        return self.policy(obs)

    def __repr__(self) -> str:
        return (
            f"PreparedPolicy({self.task}: {self.obs_dim} -> {self.act_dim}, "
            f"fingerprint {self.fingerprint})"
        )


def prepare(policy: Any, task: str, protocol: Any = None, view: Any = None) -> PreparedPolicy:
    """``policy`` made ready for evaluations of ``task`` under ``protocol`` (default: the
    policy's own, ``Protocol.for_policy``) once: adapted, checked (one-line errors), probed for
    batch invariance (a warning if its actions depend on the batch) and fingerprinted.
    ``view``: a TC-RMDP protagonist's view (default: the one its metadata records)."""
    from rrls.evaluation.protocol import Protocol
    from rrls.evaluation.stack import policy_view

    if isinstance(policy, PreparedPolicy):
        return policy
    policy = as_policy(policy)
    if protocol is None:
        protocol = Protocol.for_policy(getattr(policy, "metadata", None), task)
    plan = protocol.plan(task, policy_view(policy) if view is None else view)
    return prepare_policy(policy, Rollouts.from_plan(plan, protocol), stacklevel=3)


def prepare_policy(policy: Any, spec: Any, stacklevel: int = 3) -> PreparedPolicy:
    """Check an adapted ``policy`` (``as_policy``'s) against ``spec``'s task (a policy trained
    on another task, wrong shapes, non-numbers: one-line errors before any episode); warn once
    if its actions depend on the batch (then results may differ in the last bits from a
    one-episode loop).
    A policy already prepared for these observations is returned as it is."""
    obs_dim, act_dim = _dims(spec)
    if isinstance(policy, PreparedPolicy):
        if (policy.task, policy.obs_dim, policy.act_dim) == (spec.task, obs_dim, act_dim):
            return policy
        raise ValueError(
            f"the policy was prepared for {policy.task} ({policy.obs_dim} -> {policy.act_dim}), "
            f"not for this evaluation's {spec.task} ({obs_dim} -> {act_dim}); prepare it again"
        )
    trained_on = (getattr(policy, "metadata", None) or {}).get("task")
    if trained_on is not None and trained_on != spec.task:
        raise ValueError(f"the policy was trained on {trained_on!r}, not on task {spec.task!r}")
    _check_policy(policy, obs_dim, act_dim)
    if not is_batch_invariant(policy, obs_dim):
        warnings.warn(
            "the policy's actions depend on the batch size (BLAS kernels differ), so results may "
            "differ in the last bits from a one-episode-at-a-time loop; wrap it in "
            "rrls.evaluation.BatchInvariant(policy) for exact equality",
            stacklevel=stacklevel,
        )
    fingerprint = policy_fingerprint(policy, obs_dim)
    return PreparedPolicy(policy, spec.task, obs_dim, act_dim, fingerprint)


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


def policy_fingerprint(policy: Callable[[np.ndarray], Any], obs_dim: int, n: int = 8) -> str:
    """A short hash of the policy's actions on fixed probe observations (to guard resumes)."""
    probe = np.random.default_rng(12345).normal(size=(n, obs_dim))
    actions = np.ascontiguousarray(np.asarray(policy(probe), dtype=np.float64))
    return hashlib.sha256(actions.tobytes()).hexdigest()[:16]


def is_batch_invariant(policy: Callable[[np.ndarray], Any], obs_dim: int, n: int = 20) -> bool:
    """Whether rows of a batch call equal one-row calls on probe observations."""
    probe = np.random.default_rng(54321).normal(size=(n, obs_dim))
    batch = np.asarray(policy(probe))
    return all(
        np.array_equal(batch[i], np.asarray(policy(probe[i : i + 1]))[0], equal_nan=True)
        for i in range(n)
    )
