"""What an evaluation wraps around each bare env: disruptors, a schedule, context, the view of a
TC-RMDP Stacked or Oracle protagonist.

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
    ``context``: the set whose parameters are appended to the observation; ``view``: what a
    TC-RMDP Stacked/Oracle protagonist observes (``rrls.wrappers.tc_rmdp.View``, outermost)."""

    disruptors: tuple[tuple[str, float], ...] = ()
    schedule: Any = None  # rrls.wrappers.schedules.Schedule
    schedule_set: UncertaintySet | None = None
    context: UncertaintySet | None = None
    view: Any = None  # rrls.wrappers.tc_rmdp.View

    def __call__(self, env: Any) -> Any:
        from rrls.wrappers import ContextObservation, ScheduledParams, disrupt

        if self.disruptors:
            env = disrupt(env, **dict(self.disruptors))
        if self.schedule is not None:
            env = ScheduledParams(env, self.schedule_set, self.schedule)
        if self.context is not None:
            env = ContextObservation(env, self.context)
        if self.view is not None:
            from rrls.wrappers.tc_rmdp import ProtagonistObservation

            env = ProtagonistObservation(env, self.view)
        return env

    @property
    def empty(self) -> bool:
        return (
            not self.disruptors
            and self.schedule is None
            and self.context is None
            and self.view is None
        )

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
        if self.view is not None:
            out["protagonist_view"] = self.view.to_metadata()
        return out


def policy_view(policy: Any) -> Any:
    """The ``View`` a policy's metadata records (a TC-RMDP Stacked/Oracle protagonist trained by
    ``rrls train --algo rarl --rate-limit``), else ``None``: its evaluations show it the same
    observations it was trained on."""
    from rrls.wrappers.tc_rmdp import View

    return View.from_metadata(getattr(policy, "metadata", None))


__all__ = ["EnvStack", "policy_view"]
