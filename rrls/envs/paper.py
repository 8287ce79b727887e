"""What ``paper=True`` writes: the original RRLS code's model fields, row for row.

The paper's numbers came from the original code (SuReLI/RRLS, ``rrls/envs/<task>.py``), so the
paper's physics writes what it wrote, not rrls's corrected rows:

- ``worldfriction``: every geom's sliding friction on HalfCheetah (``half_cheetah.py:175``,
  ``geom_friction[:, 0]``, in the v4-era and the current file alike), the floor geom's only on
  Hopper (``hopper.py:137``) and Walker2d (``walker.py:169``, ``geom_friction[0, 0]``);
- masses: ``body_mass[b]`` alone, MuJoCo's derived constants (subtree masses, ``dof_M0``, the
  constraint inverse weights) left as compiled: the original never calls ``mj_setConst``;
- forces: ``xfrc_applied[b, k]`` with ``_x``, ``_y``, ``_z`` the world axes on every task (on the
  planar tasks ``_y`` is out of the plane of motion, as in the original).

Every other row (the kinds the original does not have) writes what it writes on v5.
``tests/test_paper_writes.py`` holds the original's writes, cited line by line, and checks that
each row of each paper env changes exactly those model entries.
"""

from __future__ import annotations

from rrls.params import Parameter, force_params
from rrls.registry import TaskSpec

#: tasks whose original code writes ``worldfriction`` to the floor geom only (``geom_friction[0,
#: 0]``; the floor is named ``floor`` in their XMLs), with the line of SuReLI/RRLS@0c43dc9
FLOOR_FRICTION = {"hopper": "rrls/envs/hopper.py:137", "walker": "rrls/envs/walker.py:169"}
#: fields the original writes without refreshing MuJoCo's derived constants
NO_SETCONST = frozenset({"body_mass"})


def paper_specs(task: TaskSpec, kind: str) -> tuple[Parameter, ...]:
    """The rows of ``task``'s paper env of family ``kind`` ("robust" or "force")."""
    if kind == "force":
        return _world_axis_forces(task.forces)
    rows = []
    for spec in task.params:
        if spec.name == "worldfriction" and task.key in FLOOR_FRICTION:
            spec = Parameter("worldfriction", "geom_friction", "floor")
        rows.append(spec)
    return tuple(rows)


def _world_axis_forces(forces: tuple[Parameter, ...]) -> tuple[Parameter, ...]:
    """``<part>force_x/_y/_z`` on the world axes for every part of ``forces`` (in their order)."""
    parts = {
        s.name.removesuffix("force_x"): s.target
        for s in forces
        if s.field == "xfrc_applied" and s.name.endswith("force_x")
    }
    rows = force_params(parts, planar=False)
    others = tuple(s for s in forces if s.field != "xfrc_applied")
    return rows + others


__all__ = ["FLOOR_FRICTION", "NO_SETCONST", "paper_specs"]
