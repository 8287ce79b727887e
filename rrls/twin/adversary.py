"""A point per world written on the device: the adversary's at every step (RARL's game,
``WarpTwin(..., adversary=True)``), or a fresh uniform draw at every episode (DR with
``pool=0``), into that world's fields, without a host round trip.

Why affine writes: every rrls parameter writes its model entries affinely, ``entry = c0 + c1 ·
value`` (a mass its ``body_mass`` and, scaling the inertia, its ``body_inertia`` row; a friction
its geoms' first coefficient; an offset ``ipos0 + value``; a force its ``xfrc_applied`` slot;
gravity ``-value``). So the CPU env is *probed* once, each parameter set at its box's two ends,
and the entries that move, with their ``c0`` and ``c1``, are what a kernel writes at every step:
no per-kind code to drift from ``set_params``. Masses, inertias, offsets, armature and gear feed
constants MuJoCo derives (``mj_setConst`` on the CPU); MuJoCo Warp's ``set_const`` recomputes
them per world after the writes.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from rrls.envs.base import SAVED_FIELDS

#: fields whose entries a parameter writes (the rest of the twin's fields are derived): the
#: model arrays the CPU env saves and restores, the options' and the adversary's forces
WRITTEN = (*SAVED_FIELDS, "timestep", "gravity", "xfrc_applied")
#: written fields that MuJoCo derives constants from (``set_const`` after writing them)
DERIVING = ("body_mass", "body_inertia", "body_ipos", "dof_armature", "actuator_gear")


@dataclass(frozen=True)
class Writes:
    """One field's writes: entry ``slot[e]`` (flat, per world) becomes ``c0[e] + c1[e] · v``,
    ``v`` the value of parameter ``param[e]``."""

    field: str
    slot: np.ndarray
    param: np.ndarray
    c0: np.ndarray
    c1: np.ndarray


def fields64(cpu: Any) -> dict[str, np.ndarray]:
    """The written fields of the CPU env as they stand, flat float64."""
    model, data = cpu.model, cpu.data
    got = {f: getattr(model, f) for f in WRITTEN if hasattr(model, f)}
    got["timestep"] = np.array([model.opt.timestep])
    got["gravity"] = np.array(model.opt.gravity)
    got["xfrc_applied"] = np.array(data.xfrc_applied)
    return {f: np.asarray(v, dtype=np.float64).ravel().copy() for f, v in got.items()}


def probe(cpu: Any, box: Any) -> list[Writes]:
    """Each parameter of ``box`` set alone at its low and high ends on ``cpu``: the entries that
    move, and the line through both ends (``cpu`` is reset to its nominal model after)."""
    rows: dict[str, list[tuple[int, int, float, float]]] = {}
    for i, (name, lo, hi) in enumerate(zip(box.names, box.low, box.high)):
        ends = []
        for value in (float(lo), float(hi)):
            cpu.set_params(**{name: value})
            ends.append(fields64(cpu))
            cpu.reset_params()
        for field, at_lo in ends[0].items():
            at_hi = ends[1][field]
            for slot in np.flatnonzero(at_lo != at_hi):
                c1 = (at_hi[slot] - at_lo[slot]) / (float(hi) - float(lo))
                rows.setdefault(field, []).append((int(slot), i, at_lo[slot] - c1 * lo, c1))
    out = []
    for field, entries in rows.items():
        slot, param, c0, c1 = (np.array(column) for column in zip(*entries))
        if len(set(slot.tolist())) != len(slot):  # the CPU env's order of writes would decide
            raise ValueError(f"parameters of {box.label!r} write the same {field} entries")
        out.append(
            Writes(
                field,
                slot.astype(np.int32),
                param.astype(np.int32),
                c0.astype(np.float32),
                c1.astype(np.float32),
            )
        )
    return out


class PointWrites:
    """``box``'s probed writes as device arrays: ``write(values, m, d)`` puts each world's point
    (``values``, ``(n, dim)`` warp floats) into its fields, then recomputes the derived
    constants if a written field feeds them (MuJoCo Warp's ``set_const`` derives them for every
    world: ``WarpTwin`` puts back those of worlds it does not write). ``targets``: the fields,
    ``(n, width)`` views."""

    def __init__(self, cpu: Any, box: Any, targets: dict[str, Any]) -> None:
        import warp as wp

        self.low = wp.array(np.asarray(box.low, dtype=np.float32), dtype=float)
        # DynamicAdversarial.params_of: lo + ((a + 1) * (hi - lo)) / 2 in float32, the span
        # rounded once from float64 as numpy rounds a Python float against a float32 array
        span = (np.asarray(box.high, np.float64) - box.low).astype(np.float32)
        self.span = wp.array(span, dtype=float)
        self.launches = []
        writes = probe(cpu, box)
        for w in writes:
            arrays = [wp.array(a, dtype=int) for a in (w.slot, w.param)]
            arrays += [wp.array(a, dtype=float) for a in (w.c0, w.c1)]
            self.launches.append((len(w.slot), [*arrays, targets[w.field]]))
        self.derive = any(w.field in DERIVING for w in writes)

    def write(self, values: Any, m: Any, d: Any, only: Any) -> None:
        """Each world's point into its fields, the worlds of ``only`` (a warp int mask)."""
        import mujoco_warp as mjw
        import warp as wp

        from rrls.twin import warp_kernels as kernels

        for entries, inputs in self.launches:
            wp.launch(kernels.write_point, (values.shape[0], entries), [values, only, *inputs])
        if self.derive:  # mj_setConst's derived constants, per world
            mjw.set_const(m, d)


__all__ = ["DERIVING", "WRITTEN", "PointWrites", "Writes", "fields64", "probe"]
