"""Worst-case search beyond the grid: minimise the return over the whole box with an optimiser.

A mesh only sees its points; the true worst case can sit between them. ``search_worst_case`` runs
SciPy's differential evolution over the box (a well-kept, derivative-free global optimiser that
copes with the noisy, discontinuous return of an RL policy), evaluating each generation's whole
population in one batched call of the evaluation engine. Every candidate is rolled out with the
same episode seeds (common random numbers), so candidates differ by their dynamics only.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from rrls.evaluation import lanes
from rrls.evaluation.defaults import Default, keyword_protocol
from rrls.uncertainty import UncertaintySet


@dataclass
class WorstCaseSearch:
    """The worst parameters found, their mean return, and every candidate evaluated (``trace``)."""

    task: str
    uncertainty: UncertaintySet
    params: dict[str, float]
    value: float
    trace: Any  # pandas.DataFrame: generation, parameters, mean_return, best_so_far
    episodes: int

    @property
    def evaluations(self) -> int:
        """Candidate points evaluated (each over ``episodes`` episodes)."""
        return len(self.trace)

    @property
    def episode_evaluations(self) -> int:
        return self.evaluations * self.episodes

    def __repr__(self) -> str:
        point = ", ".join(f"{k}={v:.4g}" for k, v in self.params.items())
        return (
            f"WorstCaseSearch({self.uncertainty.label}: {self.value:.2f} at {point}, "
            f"{self.evaluations} candidates x {self.episodes} episodes)"
        )


def search_worst_case(
    policy: Any,
    task: str,
    uncertainty: str | UncertaintySet | Default = Default("3d"),
    budget: int = 200,
    episodes: int | Default = Default(1),
    seed: int | Default = Default(0),
    workers: int | None = None,
    popsize: int | None = None,
    max_episode_steps: int | None | Default = Default(None),
    *,
    protocol: Any = None,
) -> WorstCaseSearch:
    """Search ``uncertainty``'s box for the parameters minimising ``policy``'s mean return.

    ``budget`` caps the candidate points evaluated (each over ``episodes`` episodes with shared
    seeds). The population (``popsize`` points, default ``max(8, 5 * dim)``) is evaluated in one
    engine call per generation. Returns the worst point, its return and the trace.
    ``max_episode_steps`` defaults to the task's episode length (1000 for the paper's tasks).

    ``protocol``: a :class:`~rrls.evaluation.Protocol` giving the set (the box searched: every
    axis its mesh would have, disruptor ranges included), ``episodes``, the seed, the physics,
    fixed disruptors and context, as ``evaluate`` reads it; the keywords (defaults: the ``"3d"``
    set, ``episodes=1``, ``seed=0``) build one for interactive use, and passing any of them beside
    it is an error naming them, whatever the value. A schedule family is not searched.
    """
    protocol = keyword_protocol(
        "search_worst_case",
        protocol,
        {
            "uncertainty": uncertainty,
            "episodes": episodes,
            "seed": seed,
            "max_episode_steps": max_episode_steps,
        },
    )
    if protocol.schedule is not None:
        raise ValueError("search_worst_case searches parameter boxes, not schedule families")
    if budget < 2:
        raise ValueError(f"budget must be >= 2, got {budget}")
    try:
        return _search(policy, task, protocol, budget, workers, popsize)
    finally:
        lanes.clear_env_cache()


def _search(
    policy: Any,
    task: str,
    protocol: Any,
    budget: int,
    workers: int | None,
    popsize: int | None,
) -> WorstCaseSearch:
    import pandas as pd
    from scipy.optimize import differential_evolution

    from rrls.evaluation.policies import as_policy
    from rrls.evaluation.prepared import PreparedPolicy, prepare_policy
    from rrls.evaluation.stack import policy_view
    from rrls.evaluation.static import rollout_table

    if not isinstance(policy, PreparedPolicy):  # prepared at the door: adapted already
        policy = as_policy(policy)
    # a TC-RMDP Stacked/Oracle protagonist sees what it trained on
    plan = protocol.plan(task, policy_view(policy))
    if plan.mesh_box.dim == 0:
        raise ValueError("the nominal model has no parameters to search over")
    key, kind, box = plan.resolved.task, plan.resolved.family, plan.mesh_box
    stack = None if plan.stack.empty else plan.stack
    episodes, max_episode_steps = protocol.episodes, plan.max_episode_steps
    dim = box.dim
    size = int(popsize or max(8, 5 * dim))
    size = min(size, budget)
    common = lanes.episode_seeds(protocol.seed, 1, episodes)  # the same for every candidate
    probe = lanes.Rollouts(
        key,
        kind,
        box.names,
        (box.low if box.nominal is None else box.nominal)[None],
        common,
        max_episode_steps,
        stack,
        plan.paper,
    )
    policy = prepare_policy(policy, probe)
    records: list[dict[str, Any]] = []

    def objective(x: np.ndarray) -> np.ndarray:
        points = np.atleast_2d(np.asarray(x).T)  # scipy passes (dim, S) when vectorised
        left = budget - len(records)
        values = np.full(len(points), np.inf)  # over budget: never selected
        run = box.clip(points[: max(0, left)])
        if len(run):
            seeds = np.repeat(common, len(run), axis=0)
            spec = lanes.Rollouts(
                key, kind, box.names, run, seeds, max_episode_steps, stack, plan.paper
            )
            table = rollout_table(spec, policy, workers)
            means = table.groupby("point")["return"].mean().to_numpy()
            generation = len(records) and records[-1]["generation"] + 1
            for point, value in zip(run, means):
                records.append(
                    {"generation": generation, **box.to_dict(point), "mean_return": float(value)}
                )
            values[: len(run)] = means
        return values

    rng = np.random.default_rng(protocol.seed)
    # Search a box 10 % wider on each side and clip candidates into the set: worst cases often
    # lie on a face or a corner, which differential evolution alone almost never reaches.
    margin = 0.1 * (box.high - box.low)
    bounds = list(zip((box.low - margin).tolist(), (box.high + margin).tolist()))
    differential_evolution(
        objective,
        bounds,
        popsize=max(1, -(-size // dim)),
        maxiter=max(1, budget // size),
        vectorized=True,
        updating="deferred",
        polish=False,
        tol=0,
        init="latinhypercube",
        rng=rng,
    )
    trace = pd.DataFrame.from_records(records)
    trace["best_so_far"] = trace["mean_return"].cummin()
    best = trace.loc[trace["mean_return"].idxmin()]
    return WorstCaseSearch(
        task=key,
        uncertainty=box,
        params={n: float(best[n]) for n in box.names},
        value=float(best["mean_return"]),
        trace=trace,
        episodes=episodes,
    )


__all__ = ["search_worst_case", "WorstCaseSearch"]
