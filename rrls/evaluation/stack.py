"""What an evaluation wraps around each bare env: disruptors, a schedule, context.

A small frozen (hashable, picklable) description, so the engine can cache one stack per lane
and worker processes can rebuild it. Calling it on a bare env returns the wrapped env; each row
then does ``env.reset_params(); env.set_params(**point); env.reset(seed=seed)``, exactly the
one-episode loop on the same stack.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from rrls.uncertainty import UncertaintySet


@dataclass(frozen=True)
class EnvStack:
    """``disruptors``: (name, constructor strength) pairs; ``schedule`` over ``schedule_set``;
    ``context``: the set whose parameters are appended to the observation (outermost)."""

    disruptors: tuple[tuple[str, float], ...] = ()
    schedule: Any = None  # rrls.wrappers.schedules.Schedule
    schedule_set: UncertaintySet | None = None
    context: UncertaintySet | None = None

    def __call__(self, env: Any) -> Any:
        from rrls.wrappers import ContextObservation, ScheduledParams, disrupt

        if self.disruptors:
            env = disrupt(env, **dict(self.disruptors))
        if self.schedule is not None:
            env = ScheduledParams(env, self.schedule_set, self.schedule)
        if self.context is not None:
            env = ContextObservation(env, self.context)
        return env

    @property
    def empty(self) -> bool:
        return not self.disruptors and self.schedule is None and self.context is None

    def to_json(self) -> dict[str, Any]:
        """What ``evaluation.json``/``summary.json`` record of the stack."""
        out: dict[str, Any] = {}
        if self.disruptors:
            out["disruptors"] = dict(self.disruptors)
        if self.schedule is not None:
            out["schedule"] = self.schedule.to_json()
            out["schedule_set"] = self.schedule_set.as_bounds()
        if self.context is not None:
            out["context"] = list(self.context.names)
        return out
