"""The twin against CPU MuJoCo, world by world: each world's state, reward and termination after
``t`` env steps against a CPU env at the same point, from the same state, under the same actions.

Used by the tests (1 and 10 steps, per task and per parameter kind, on warp's CPU device) and by
``benchmarks/twin_check.py`` (the docs' table and the 100- and 1 000-step divergence figure).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from rrls.envs import nominal_params, resolve
from rrls.params import FIELDS, KINDS
from rrls.twin.catalog import UNSUPPORTED_FIELDS
from rrls.twin.env import WarpTwin, default_set
from rrls.uncertainty import UncertaintySet

#: the kinds a twin carries (``viscosity`` is refused, see ``UNSUPPORTED_FIELDS``)
TWIN_KINDS = tuple(k for k, fields in KINDS.items() if not set(fields) & set(UNSUPPORTED_FIELDS))


def kind_set(task: str, kind: str, spread: float = 0.3) -> UncertaintySet:
    """A box over one kind's parameters of ``task``: nominal x (1 +- spread); around a zero
    nominal, +-0.02 (centre-of-mass offsets) or [0, spread] (a field that must be >= 0, dry
    friction); forces: the task's ``rarl`` set."""
    if kind == "force":
        return resolve(task, "rarl").box
    cls = resolve(task, default_set(task)).env_class
    fields = set(KINDS[kind])
    specs = [s for s in cls.param_specs if s.field in fields]
    names = [s.name for s in specs]
    if not names:
        raise ValueError(f"task {task!r} has no {kind!r} parameters")
    nominal = nominal_params(task)
    low, high = [], []
    for spec in specs:
        v = nominal[spec.name]
        signed = FIELDS[spec.field].low < 0
        low.append(v * (1 - spread) if v else (-0.02 if signed else 0.0))
        high.append(v * (1 + spread) if v else (0.02 if signed else spread))
    return UncertaintySet(tuple(names), low, high, label=f"{task}/{kind}")


def cpu_env_at(resolved: Any, point: Any, qpos: Any, qvel: Any, seed: int = 0) -> Any:
    """A bare CPU env of ``resolved``'s family at ``point`` (over its box's names), put at a
    twin world's state (float32, widened): the other side of every twin-vs-CPU comparison."""
    env = resolved.make_env()
    env.reset(seed=seed)
    env.set_params(**dict(zip(resolved.box.names, np.asarray(point).tolist(), strict=True)))
    env.set_state(np.asarray(qpos, np.float64), np.asarray(qvel, np.float64))
    return env


@dataclass(frozen=True)
class Divergence:
    """Per env step (row) the largest ``|qpos - qpos_cpu|``, ``|qvel - qvel_cpu|`` and
    ``|reward - reward_cpu|`` over the worlds still in their first episode, and the number of
    worlds whose termination differed."""

    qpos: np.ndarray
    qvel: np.ndarray
    reward: np.ndarray
    termination_mismatches: int
    worlds: int


def divergence(
    task: str,
    uncertainty: str | UncertaintySet,
    worlds: int = 4,
    steps: int = 10,
    seed: int = 0,
    device: str = "cpu",
) -> Divergence:
    """Step a twin and one CPU env per world side by side from the twin's reset state."""
    resolved = resolve(task, uncertainty)
    rng = np.random.default_rng(seed)
    points = np.asarray(resolved.box.sample(rng, worlds)).reshape(worlds, resolved.box.dim)
    twin = WarpTwin(task, worlds, resolved.box, points=points, seed=seed, device=device)
    twin.reset()
    qpos, qvel = twin.state()
    cpus = []
    for w in range(worlds):
        cpus.append(cpu_env_at(resolved, points[w], qpos[w], qvel[w], seed))
    low, high = twin.single_action_space.low, twin.single_action_space.high
    alive = np.ones(worlds, dtype=bool)
    out = {"qpos": [], "qvel": [], "reward": []}
    mismatches = 0
    for _ in range(steps):
        action = rng.uniform(low, high, size=(worlds, len(low))).astype(np.float32)
        _, reward, terminated, _, _ = twin.step(action)
        tq, tv = twin.state()
        dq, dv, dr = [], [], []
        for w, env in enumerate(cpus):
            if not alive[w]:
                continue
            _, r, term, _, _ = env.step(action[w].astype(np.float64))
            if bool(term) != bool(terminated[w]):
                mismatches += 1
            if term or terminated[w]:  # the twin has reset this world: compare no further
                alive[w] = False
                continue
            dq.append(np.abs(tq[w] - env.data.qpos).max())
            dv.append(np.abs(tv[w] - env.data.qvel).max())
            dr.append(abs(float(reward[w]) - float(r)))
        out["qpos"].append(max(dq, default=np.nan))
        out["qvel"].append(max(dv, default=np.nan))
        out["reward"].append(max(dr, default=np.nan))
    twin.close()
    for env in cpus:
        env.close()
    return Divergence(
        np.array(out["qpos"]), np.array(out["qvel"]), np.array(out["reward"]), mismatches, worlds
    )


__all__ = ["TWIN_KINDS", "Divergence", "cpu_env_at", "divergence", "kind_set"]
