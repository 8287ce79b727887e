"""The evaluation protocol as one frozen, serialisable object: what a benchmark stores, a run
records, a submitted policy is evaluated under and a reference file is compared against.

>>> from rrls.evaluation import Protocol
>>> protocol = Protocol("2d", mesh=3, episodes=2)
>>> Protocol.from_json(protocol.to_json()) == protocol
True
>>> protocol.plan("invertedpendulum").points.shape
(9, 2)

``Protocol.plan(task)`` turns it into what the engine runs for one task: the mesh's box and
points, the env family, the wrapper stack (disruptors, schedule, context, the protagonist's
view), each point's in/out-of-distribution flag under a split, and the settings
``summary.json`` records. ``rrls.evaluation.evaluate(policy, task, protocol=...)`` evaluates a
policy under it; its keyword arguments (``uncertainty``, ``mesh``, ``episodes``...) build one
for interactive use.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass, field, replace
from typing import Any, NamedTuple

import numpy as np

from rrls.evaluation.limits import (
    MAX_EPISODES,
    MAX_LANES,
    MAX_WORKERS,
    check_counts,
    check_episodes,
    check_rate_limit,
    check_seed,
    check_sizes,
)
from rrls.evaluation.recheck_settings import Recheck
from rrls.physics import is_paper, physics_label
from rrls.uncertainty import BOX_SCHEMA, SPLIT_SCHEMA, Split, UncertaintySet, check_box
from rrls.wrappers.tc_rmdp import RATE_GAMES

__all__ = [
    "MAX_EPISODES",
    "MAX_LANES",
    "MAX_WORKERS",
    "Plan",
    "Protocol",
    "Recheck",
    "check_counts",
    "check_episodes",
    "check_protocol_alone",
    "check_rate_limit",
    "check_seed",
    "check_sizes",
]

SPLIT_KEYS = ("kind", "names", "low", "high", "region_low", "region_high")


def check_protocol_alone(
    caller: str, protocol: Any, given: Mapping[str, bool], fields: Mapping[str, str] | None = None
) -> None:
    """Refuse a ``protocol`` that is not a :class:`Protocol`, or one given beside keywords it
    holds (``given``: keyword -> whether the caller got it; ``fields``: the protocol field a
    keyword stands for, for the hint): the keyword would be ignored, so one line names it."""
    if not isinstance(protocol, Protocol):
        raise TypeError(f"protocol must be an rrls.evaluation.Protocol, got {protocol!r}")
    both = [name for name, differs in given.items() if differs]
    if both:
        field = (fields or {}).get(both[0], both[0])
        raise ValueError(
            f"{caller} got protocol= and {', '.join(both)}: give the protocol alone (with "
            f"protocol.replace({field}=...) for another value) or the keywords alone"
        )


class Plan(NamedTuple):
    """A protocol applied to one task: what the engine runs."""

    mesh_box: UncertaintySet  # the meshed axes (physical, disruptor strengths, schedule fields)
    resolved: Any  # ``rrls.envs.resolve``'s answer: task, env family, physical box
    stack: Any  # ``rrls.evaluation.stack.EnvStack``: the wrappers every episode runs in
    points: np.ndarray  # (n_points, n_axes)
    in_distribution: np.ndarray | None  # per point, under a split
    max_episode_steps: int
    paper: bool
    settings: dict[str, Any]  # what ``summary.json`` records of the protocol


@dataclass(frozen=True)
class Protocol:
    """How a policy is evaluated (paper §4, and rrls's extensions beyond static dynamics).

    ``uncertainty``: a set's name or an ``UncertaintySet``; ``mesh``: points per dimension;
    ``endpoint``: whether the mesh reaches the upper bounds (default: yes, except on the paper's
    physics, whose ``np.arange`` mesh stops short); ``episodes`` per point, their seeds drawn
    from ``seed``; ``physics``: ``v5`` or ``paper``; ``split``: a ``Split`` or its text
    (``extrapolation:0.5``, resolved against each task's set); ``disruptors``: fixed strengths
    or meshed ``(low, high)`` ranges; ``schedule``: a ``ScheduleFamily`` (the mesh is then its
    grid); ``context``: the set's normalised parameters appended to the observation;
    ``max_episode_steps``: default the task's. The dynamic evaluation (RARL/NR-MDP against their
    own adversary) plays ``dynamic_episodes``, under TC-RMDP's ``rate_limit``/``rate_game``
    when set.
    """

    uncertainty: str | UncertaintySet = "3d"
    # the help of the options that set them (rrls evaluate, rrls benchmark: rrls.cli.run_options)
    mesh: int = field(default=10, metadata={"help": "points per dimension of the mesh"})
    episodes: int = field(default=5, metadata={"help": "episodes per point of the mesh"})
    seed: int = 0
    physics: str = "v5"
    endpoint: bool | None = None
    split: str | Split | None = None
    disruptors: tuple[tuple[str, Any], ...] = ()
    schedule: Any = None
    context: bool = False
    max_episode_steps: int | None = None
    dynamic_episodes: int = field(
        default=10, metadata={"help": "episodes against the run's own adversary (paper Table 6)"}
    )
    rate_limit: float | None = field(
        default=None,
        metadata={
            "metavar": "L",
            "help": "the dynamic evaluation's adversary is TC-RMDP's time-constrained one, as "
            "its authors play it: each step it moves every parameter by at most L in raw "
            "parameter units (psi <- clip(psi + a * L, box); the authors train with 0.001), "
            "episodes start uniformly in the box, the adversary sees psi and the state",
            "none": "none, an unconstrained adversary",
        },
    )
    rate_game: str = "tc"
    #: a worst case that resists episode noise, beside the paper's (``rrls.evaluation.recheck``):
    #: the lowest points re-evaluated with fresh episodes; None: not computed
    recheck: Any = field(
        default=None,
        metadata={
            "metavar": "KxE",
            "help": "also recheck each run's worst case: its K lowest mesh points re-evaluated "
            "with E fresh episodes each, and the 5th percentile of its point means, beside the "
            "paper's minimum (e.g. 10x20; 10x20@0.1 for the 10th percentile; "
            "docs/evaluation.md)",
            "none": "none",
        },
    )

    def __post_init__(self) -> None:
        if self.recheck is not None:
            if isinstance(self.recheck, Mapping):
                object.__setattr__(self, "recheck", Recheck.from_json(dict(self.recheck)))
            elif not isinstance(self.recheck, Recheck):
                raise ValueError(f"recheck must be a Recheck or None, got {self.recheck!r:.80}")
        check_counts(mesh=self.mesh, episodes=self.episodes)
        check_counts(dynamic_episodes=self.dynamic_episodes)
        if self.max_episode_steps is not None:
            check_counts(max_episode_steps=self.max_episode_steps)
        seed = self.seed
        check_seed(seed)
        if not isinstance(self.uncertainty, (str, UncertaintySet)):
            raise ValueError(
                f"uncertainty must be a set's name or an UncertaintySet, got {self.uncertainty!r}"
            )
        for name in ("endpoint", "context"):  # JSON's true/false, not "no" or "false"
            value = getattr(self, name)
            if not isinstance(value, bool) and not (name == "endpoint" and value is None):
                valid = "true, false or null" if name == "endpoint" else "true or false"
                raise ValueError(f"{name} must be {valid}, got {value!r}")
        if not isinstance(self.physics, str):
            raise ValueError(f"physics must be v5 or paper, got {self.physics!r}")
        if self.split is not None and not isinstance(self.split, (str, Split)):
            raise ValueError(f"split must be a split's text or a Split, got {self.split!r}")
        check_rate_limit(self.rate_limit)
        if self.rate_game not in RATE_GAMES:
            raise ValueError(
                f"rate_game must be one of {', '.join(RATE_GAMES)}, got {self.rate_game!r}"
            )
        object.__setattr__(self, "physics", physics_label(self.physics))
        if isinstance(self.disruptors, Mapping):
            object.__setattr__(self, "disruptors", tuple(self.disruptors.items()))
        if not isinstance(self.disruptors, (list, tuple)) or not all(
            isinstance(p, (list, tuple)) and len(p) == 2 and isinstance(p[0], str)
            for p in self.disruptors
        ):
            raise ValueError(
                f"disruptors must be name: strength pairs (a strength, or [low, high]), got "
                f"{self.disruptors!r:.80}"
            )
        for name, value in self.disruptors:
            values = value if isinstance(value, (list, tuple, np.ndarray)) else [value]
            if not all(
                isinstance(x, (int, float, np.number))
                and not isinstance(x, bool)
                and np.isfinite(x)
                for x in values
            ):
                raise ValueError(
                    f"disruptor {name!r}: its strength must be a finite number or [low, high], "
                    f"got {value!r}"
                )
        pairs = tuple(
            (str(n), tuple(float(x) for x in v) if isinstance(v, (list, tuple, np.ndarray)) else v)
            for n, v in self.disruptors
        )
        object.__setattr__(self, "disruptors", pairs)

    @property
    def paper(self) -> bool:
        return is_paper(self.physics)

    def replace(self, **changes: Any) -> Protocol:
        return replace(self, **changes)

    # --- serialisation ---------------------------------------------------------------------

    def to_json(self) -> dict[str, Any]:
        data = asdict(self)
        if isinstance(self.uncertainty, UncertaintySet):
            box = self.uncertainty
            data["uncertainty"] = {
                "names": list(box.names),
                "low": box.low.tolist(),
                "high": box.high.tolist(),
                "nominal": None if box.nominal is None else np.asarray(box.nominal).tolist(),
                "label": box.label,
                "family": box.family,
            }
        if isinstance(self.split, Split):
            data["split"] = self.split.to_json()
        if self.schedule is not None:
            data["schedule"] = self.schedule.to_json()
        data["disruptors"] = [
            [n, list(v) if isinstance(v, tuple) else v] for n, v in self.disruptors
        ]
        if self.recheck is None:  # a protocol written before the recheck existed reads the same
            del data["recheck"]
        else:
            data["recheck"] = self.recheck.to_json()
        return data

    @classmethod
    def for_policy(cls, metadata: Mapping[str, Any] | None, task: str, **given: Any) -> Protocol:
        """The protocol a policy is evaluated under by default: the set it was trained on (if
        ``task`` has it; else the task's benchmark set), its physics, its split when the set is
        its own; every field in ``given`` that is not None (``uncertainty``, ``mesh``,
        ``physics``, ``split``...) overrides. What ``rrls evaluate POLICY`` runs."""
        from rrls.tasks import benchmark_set, get_task

        meta = dict(metadata or {})
        fields = {k: v for k, v in given.items() if v is not None}
        unknown = sorted(set(fields) - set(cls.__dataclass_fields__))
        if unknown:
            raise ValueError(f"not protocol fields: {', '.join(unknown)}")
        spec = get_task(task)
        trained = meta.get("uncertainty")
        own = isinstance(trained, str) and trained.lower() in (*spec.sets, "nominal")
        fields.setdefault("uncertainty", trained.lower() if own else benchmark_set(spec.key))
        if "physics" not in fields:
            fields["physics"] = physics_label(is_paper(meta.get("physics")))
        if "split" not in fields and fields["uncertainty"] == meta.get("uncertainty"):
            fields["split"] = meta.get("split") or None
        return cls(**fields)

    def fingerprint(self) -> str:
        """16 hex digits naming this protocol's fields (``rrls.files.json_fingerprint``): what a
        run's ``result.json`` records, so a result copied from another protocol is refused.
        ``recheck`` is left out: it changes none of the mesh's rows, and each result records
        its own recheck settings."""
        from rrls.files import json_fingerprint

        data = self.to_json()
        data.pop("recheck", None)  # adds statistics beside the mesh's; changes none of its rows
        return json_fingerprint(data)

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> Protocol:
        """The inverse of ``to_json`` (unknown keys, wrong types and values are refused)."""
        if not isinstance(data, Mapping):
            raise ValueError(f"a protocol is a JSON object of fields, got {data!r:.60}")
        known = set(cls.__dataclass_fields__)
        unknown = sorted(set(data) - known)
        if unknown:
            raise ValueError(f"not protocol fields: {', '.join(unknown)}; valid: {sorted(known)}")
        kw = dict(data)
        box = kw.get("uncertainty")
        for part, need in ((box, ("names", "low", "high")), (kw.get("split"), SPLIT_KEYS)):
            if isinstance(part, Mapping) and not set(need) <= set(part):
                missing = ", ".join(sorted(set(need) - set(part)))
                raise ValueError(f"protocol field missing {missing} in {dict(part)!r:.80}")
        if isinstance(box, Mapping):
            check_box(box, BOX_SCHEMA, "protocol", "uncertainty")
            kw["uncertainty"] = UncertaintySet(
                tuple(box["names"]),
                box["low"],
                box["high"],
                box.get("nominal"),
                box.get("label", ""),
                box.get("family"),
            )
        if isinstance(kw.get("split"), Mapping):
            check_box(kw["split"], SPLIT_SCHEMA, "protocol", "split")
            kw["split"] = Split.from_json(kw["split"])
        if kw.get("schedule") is not None:
            kw["schedule"] = _schedule_family(kw["schedule"])
        pairs = kw.get("disruptors", ())
        if isinstance(pairs, list) and all(isinstance(p, list) and len(p) == 2 for p in pairs):
            pairs = tuple((n, tuple(v) if isinstance(v, list) else v) for n, v in pairs)
        kw["disruptors"] = pairs  # anything else: refused by the constructor, by name
        return cls(**kw)

    # --- planning ----------------------------------------------------------------------------

    def plan(self, task: str, view: Any = None) -> Plan:
        """This protocol on ``task``: every check made before any episode runs."""
        from rrls.envs import paper_class
        from rrls.tasks import get_task

        mesh_box, resolved, stack = _stack(
            task, self.uncertainty, dict(self.disruptors), self.schedule, self.context, view
        )
        steps = self.max_episode_steps or get_task(resolved.task).max_episode_steps
        endpoint = (not self.paper) if self.endpoint is None else self.endpoint
        if self.paper:
            paper_class(resolved.env_class)  # a task without paper physics: refused now
        if self.schedule is None:
            points = mesh_box.mesh(self.mesh, endpoint=endpoint)
        else:
            points = _product(
                self.schedule.points(), _ranged(mesh_box, self.schedule).mesh(self.mesh, endpoint)
            )
        _check_strengths(mesh_box, points)
        check_episodes(len(points), self.episodes)  # before any per-episode array is made
        settings = {
            "physics": physics_label(self.paper),
            "mesh": self.mesh,
            "endpoint": endpoint,
            "episodes": self.episodes,
            "seed": self.seed,
            "max_episode_steps": steps,
            **stack.to_json(),
        }
        if self.schedule is not None:  # what was meshed: the family's grid
            settings["schedule"] = self.schedule.to_json()
        in_dist = None
        split = self.split
        if isinstance(split, str):
            split = Split.parse(resolved.box, split)
        if split is not None:
            in_dist = _split_mask(split, mesh_box, points, self.schedule)
            settings["split"] = split.to_json()
        return Plan(mesh_box, resolved, stack, points, in_dist, steps, self.paper, settings)


def _schedule_family(data: Any) -> Any:
    """The ``ScheduleFamily`` its JSON (``{"kind": ..., "grid": {field: [values]}}``) names."""
    from rrls.wrappers import ScheduleFamily

    if not (
        isinstance(data, Mapping)
        and set(data) == {"kind", "grid"}
        and isinstance(data["kind"], str)
        and isinstance(data["grid"], Mapping)
        and all(isinstance(v, list) for v in data["grid"].values())
    ):
        raise ValueError(
            'schedule must be null or {"kind": a schedule, "grid": {field: [values]}}, got '
            f"{data!r:.80}"
        )
    return ScheduleFamily(data["kind"], **data["grid"])


def _stack(
    task: str,
    uncertainty: str | UncertaintySet,
    disruptors: Mapping[str, float | Sequence[float]],
    schedule: Any,
    context: bool,
    view: Any,
) -> tuple[UncertaintySet, Any, Any]:
    """(the box of the mesh's names, the resolved physical set, the wrapper stack).

    The mesh's names are the set's (physical ones first resolved as usual, disruptor strengths
    kept) plus the meshed ``disruptors``; under a ``schedule`` the schedule's fields come first.
    """
    from rrls.envs import resolve
    from rrls.evaluation.stack import EnvStack
    from rrls.wrappers import DISRUPTORS, ScheduleFamily

    physical, ranged = _physical_part(uncertainty, DISRUPTORS)
    fixed: dict[str, float] = {}
    for name, value in disruptors.items():
        if name not in DISRUPTORS:
            raise ValueError(f"unknown disruptor {name!r}; valid: {', '.join(DISRUPTORS)}")
        if name in ranged:
            raise ValueError(f"{name} is both in the set and in disruptors; give it once")
        if isinstance(value, (tuple, list, np.ndarray)):
            if len(value) != 2:
                raise ValueError(f"disruptor {name} takes a strength or (low, high), got {value!r}")
            ranged[name] = (float(value[0]), float(value[1]))
        else:
            fixed[name] = value
    checks = [(n, v) for n, (lo, hi) in ranged.items() for v in (lo, hi)] + list(fixed.items())
    for name, v in checks:
        problem = DISRUPTORS[name].check_param(name, v)
        if problem:
            raise ValueError(problem)
    resolved = resolve(task, physical)
    extra = UncertaintySet.from_bounds(
        {n: list(b) for n, b in ranged.items()}, {n: 0.0 for n in ranged}
    )
    if schedule is not None:
        if not isinstance(schedule, ScheduleFamily):
            raise TypeError(
                f"schedule must be a ScheduleFamily (the grid to mesh over), got "
                f"{type(schedule).__name__}"
            )
        if resolved.is_nominal:
            raise ValueError("a schedule needs a set to move in; give a non-empty uncertainty set")
        grid = schedule.points()
        head = UncertaintySet(schedule.names, grid.min(axis=0), grid.max(axis=0), grid[0])
    else:
        head = resolved.box
    mesh_box = UncertaintySet(
        head.names + extra.names,
        np.r_[head.low, extra.low],
        np.r_[head.high, extra.high],
        np.r_[head.nominal, extra.nominal],
        head.label or resolved.label,
        resolved.family,
    )
    stack = EnvStack(
        disruptors=tuple(
            (n, float(fixed.get(n, 0.0))) for n in DISRUPTORS if n in fixed or n in ranged
        ),
        schedule=None if schedule is None else schedule.schedule,
        schedule_set=None if schedule is None else resolved.box,
        context=(resolved.box if schedule is not None else mesh_box) if context else None,
        view=view,
    )
    if context and stack.context.dim == 0:
        raise ValueError("context=True needs a non-empty set whose parameters to show")
    return mesh_box, resolved, stack


def _physical_part(
    uncertainty: str | UncertaintySet, disruptors: Mapping[str, Any]
) -> tuple[str | UncertaintySet, dict[str, tuple[float, float]]]:
    """A set naming disruptor strengths split into its physical part and the strengths' ranges."""
    if not (isinstance(uncertainty, UncertaintySet) and set(uncertainty.names) & set(disruptors)):
        return uncertainty, {}
    box = uncertainty
    ranged = {
        n: (float(lo), float(hi))
        for n, lo, hi in zip(box.names, box.low, box.high)
        if n in disruptors
    }
    names = [n for n in box.names if n not in disruptors]
    if not names:
        return "nominal", ranged
    at = [box.names.index(n) for n in names]
    nominal = None if box.nominal is None else [box.nominal[i] for i in at]
    physical = UncertaintySet(
        tuple(names),
        [box.low[i] for i in at],
        [box.high[i] for i in at],
        nominal,
        box.label,
        box.family,
    )
    return physical, ranged


def _check_strengths(mesh_box: UncertaintySet, points: np.ndarray) -> None:
    """Refuse, before any episode, a mesh whose disruptor strengths are invalid (a delay of
    1.5 steps: a mesh over a delay needs points that are whole numbers)."""
    from rrls.wrappers import DISRUPTORS

    for i, name in enumerate(mesh_box.names):
        if name not in DISRUPTORS:
            continue
        for value in np.unique(points[:, i]).tolist():
            problem = DISRUPTORS[name].check_param(name, value)
            if problem:
                raise ValueError(
                    f"the mesh has {name}={value:g}: {problem}; choose the bounds and mesh size "
                    "so every point is valid (e.g. (0, 3) with 4 points for a delay)"
                )


def _ranged(mesh_box: UncertaintySet, schedule: Any) -> UncertaintySet:
    """The meshed disruptor axes that follow a schedule's fields in ``mesh_box``."""
    k = len(schedule.names)
    return UncertaintySet(mesh_box.names[k:], mesh_box.low[k:], mesh_box.high[k:])


def _product(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Every row of ``a`` with every row of ``b`` (``a`` varying slowest)."""
    return np.hstack([np.repeat(a, len(b), axis=0), np.tile(b, (len(a), 1))])


def _split_mask(split: Split, mesh_box: UncertaintySet, points: np.ndarray, schedule: Any) -> Any:
    """``in_distribution`` of each mesh point (the split's names are a part of the mesh's)."""
    if not isinstance(split, Split):
        raise TypeError(f"split must be an rrls.uncertainty.Split, got {type(split).__name__}")
    if schedule is not None:
        raise ValueError("a split divides a set's mesh; it does not apply to a schedule family")
    missing = [n for n in split.box.names if n not in mesh_box.names]
    if missing:
        raise ValueError(f"the split names {missing}, which the mesh does not vary")
    cols = [mesh_box.names.index(n) for n in split.box.names]
    return np.asarray(split.in_distribution(points[:, cols]), dtype=bool).reshape(len(points))
