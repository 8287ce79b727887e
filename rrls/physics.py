"""The two physics a number can come from, and their one vocabulary.

Every result records which physics produced it (``summary.json``, ``run.json``, the policies'
metadata, ``benchmark.json``, reference files), always with one of these labels, the words
``--physics`` takes:

- ``v5`` (default): Gymnasium v5 envs with rrls's corrected parameter semantics;
- ``paper``: the paper's physics (the Gymnasium v5 envs the original code built, its parameter
  writes: :mod:`rrls.envs.paper`, the ``np.arange`` mesh), what ``paper=True`` builds.

Files written before the labels were the command-line words say ``rrls-v5`` (the shipped
``quick`` files still do): it is read as ``v5``, so every comparison goes through
:func:`physics_label`. ``paper-v4`` and ``v4`` named the paper's physics when ``paper=True``
built Gymnasium v4 envs; it builds v5 now (``docs/differences.md``), so those labels are refused
with a one-line error rather than read as physics they did not run. Nothing here imports
anything: every layer may use it.
"""

from __future__ import annotations

from typing import Any

V5 = "v5"
PAPER = "paper"
LABELS = (V5, PAPER)
#: what may step a run's training envs (``--simulator``): CPU MuJoCo, the reference, or the
#: task's MuJoCo Warp twin (``rrls.twin``); every evaluation runs on CPU MuJoCo either way
SIMULATORS = ("mujoco", "warp")
#: what ``--physics`` and older files say -> the label
ALIASES = {V5: V5, "rrls": V5, "rrls-v5": V5, PAPER: PAPER}
#: labels of physics rrls no longer builds -> why (a file carrying one ran other physics)
RETIRED = dict.fromkeys(
    ("v4", "paper-v4"), "the paper's physics on Gymnasium v4, which paper=True built before v5"
)


def physics_label(value: Any = None) -> str:
    """The label of ``value``: a label, an alias, ``paper=`` as a bool, or None (the default);
    anything else is a one-line ``ValueError`` naming the valid ones."""
    if value is None or value is False:
        return V5
    if value is True:
        return PAPER
    key = str(value).strip().lower() if isinstance(value, str) else None
    if key in RETIRED:
        raise ValueError(
            f"physics {value!r} is {RETIRED[key]}; not built in any more: valid: {V5} or "
            f"{PAPER} (for v4, register_task(..., paper_env='<Task>-v4') under a key of your own)"
        )
    label = ALIASES.get(key) if key is not None else None
    if label is None:
        raise ValueError(f"unknown physics {value!r}; valid: {V5} or {PAPER}")
    return label


def is_paper(value: Any) -> bool:
    """Whether ``value`` names the paper's physics (``paper=True`` for the env constructors)."""
    return physics_label(value) == PAPER


__all__ = ["ALIASES", "is_paper", "LABELS", "PAPER", "physics_label", "RETIRED", "SIMULATORS", "V5"]
