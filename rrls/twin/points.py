"""A twin world's parameter point and the model fields it gives, as CPU MuJoCo computes them:
the pool of points the worlds draw from and each point's packed fields (the derived constants
that ``mj_setConst`` recomputes included), copied into MuJoCo Warp's batched fields."""

from __future__ import annotations

from typing import Any

import numpy as np

#: MuJoCo Warp's batched model fields that rrls's kinds write or ``mj_setConst`` derives
MODEL_FIELDS = (
    "body_mass",
    "body_inertia",
    "body_ipos",
    "body_subtreemass",
    "body_invweight0",
    "geom_friction",
    "dof_damping",
    "dof_armature",
    "dof_frictionloss",
    "dof_invweight0",
    "actuator_gear",
    "actuator_acc0",
)
#: the pool's stream: a spawn key no world uses
POOL_KEY = 2**31 - 1


def model_fields(model: Any, data: Any) -> dict[str, np.ndarray]:
    """The fields a twin world copies from a CPU model and data as they stand."""
    got = {f: getattr(model, f) for f in MODEL_FIELDS}
    got["timestep"] = np.array([model.opt.timestep])
    got["gravity"] = np.array(model.opt.gravity)
    got["xfrc_applied"] = np.array(data.xfrc_applied)
    return got


def pool_points(box: Any, n: int, points: Any, dr: bool, size: int, seed: Any) -> np.ndarray:
    """The points ``n`` worlds draw from: the given ones (one per world), a seeded uniform pool
    of ``size`` points of the set (DR), or the nominal point."""
    dim = box.dim
    if points is not None:
        pts = np.asarray(points, dtype=np.float64)
        if pts.shape != (n, dim):
            raise ValueError(
                f"points has shape {pts.shape}; expected ({n}, {dim}): one row "
                f"per world over {list(box.names)}"
            )
        for row in pts:
            if not box.contains(row):
                raise ValueError(f"point {row.tolist()} lies outside {box.label}")
        return pts
    if dr:
        if not isinstance(size, int) or size < 1:
            raise ValueError(
                f"pool must be a positive integer (0: a point of the box per episode), got {size!r}"
            )
        entropy = int(seed) if isinstance(seed, (int, np.integer)) else [int(x) for x in seed]
        rng = np.random.default_rng(np.random.SeedSequence(entropy, spawn_key=(POOL_KEY,)))
        return np.asarray(box.sample(rng, size), dtype=np.float64).reshape(size, dim)
    return np.asarray(box.nominal, dtype=np.float64).reshape(1, dim)


def host_fields(cpu: Any, box: Any, pts: np.ndarray) -> dict[str, np.ndarray]:
    """Each point's packed fields, as ``cpu`` (an rrls env) at that point holds them (float32);
    ``cpu`` is back at its nominal model after."""
    rows: dict[str, list[np.ndarray]] = {}
    for p in pts:
        cpu.set_params(**dict(zip(box.names, p.tolist(), strict=True)))
        for f, v in model_fields(cpu.model, cpu.data).items():
            rows.setdefault(f, []).append(np.asarray(v, dtype=np.float32).ravel())
    cpu.reset_params()
    return {f: np.stack(v) for f, v in rows.items()}


__all__ = ["MODEL_FIELDS", "POOL_KEY", "host_fields", "model_fields", "pool_points"]
