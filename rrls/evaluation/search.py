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
    uncertainty: str | UncertaintySet = "3d",
    budget: int = 200,
    episodes: int = 1,
    seed: int = 0,
    workers: int | None = None,
    popsize: int | None = None,
    max_episode_steps: int | None = None,
) -> WorstCaseSearch:
    """Search ``uncertainty``'s box for the parameters minimising ``policy``'s mean return.

    ``budget`` caps the candidate points evaluated (each over ``episodes`` episodes with shared
    seeds). The population (``popsize`` points, default ``max(8, 5 * dim)``) is evaluated in one
    engine call per generation. Returns the worst point, its return and the trace.
    ``max_episode_steps`` defaults to the task's episode length (1000 for the paper's tasks).
    """
    from rrls.envs import resolve
    from rrls.tasks import get_task

    resolved = resolve(task, uncertainty)
    if max_episode_steps is None:
        max_episode_steps = get_task(resolved.task).max_episode_steps
    if resolved.is_nominal:
        raise ValueError("the nominal model has no parameters to search over")
    if budget < 2 or episodes < 1:
        raise ValueError(f"budget must be >= 2 and episodes >= 1, got {budget}, {episodes}")
    try:
        return _search(
            policy, resolved, budget, episodes, seed, workers, popsize, max_episode_steps
        )
    finally:
        lanes.clear_env_cache()


def _search(
    policy: Any,
    resolved: Any,
    budget: int,
    episodes: int,
    seed: int,
    workers: int | None,
    popsize: int | None,
    max_episode_steps: int,
) -> WorstCaseSearch:
    import pandas as pd
    from scipy.optimize import differential_evolution

    from rrls.evaluation.policies import as_policy
    from rrls.evaluation.prepare import prepare_policy
    from rrls.evaluation.stack import EnvStack, policy_view
    from rrls.evaluation.static import rollout_table

    key, box, kind = resolved.task, resolved.box, resolved.family
    policy = as_policy(policy)
    view = policy_view(policy)  # a TC-RMDP Stacked/Oracle protagonist sees what it trained on
    stack = None if view is None else EnvStack(view=view)
    dim = box.dim
    size = int(popsize or max(8, 5 * dim))
    size = min(size, budget)
    common = lanes.episode_seeds(seed, 1, episodes)  # the same seeds for every candidate
    probe = lanes.RolloutSpec(
        key, kind, box.names, box.nominal[None], common, max_episode_steps, stack
    )
    policy = prepare_policy(policy, probe).policy
    records: list[dict[str, Any]] = []

    def objective(x: np.ndarray) -> np.ndarray:
        points = np.atleast_2d(np.asarray(x).T)  # scipy passes (dim, S) when vectorised
        left = budget - len(records)
        values = np.full(len(points), np.inf)  # over budget: never selected
        run = box.clip(points[: max(0, left)])
        if len(run):
            seeds = np.repeat(common, len(run), axis=0)
            spec = lanes.RolloutSpec(key, kind, box.names, run, seeds, max_episode_steps, stack)
            table = rollout_table(spec, policy, workers)
            means = table.groupby("point")["return"].mean().to_numpy()
            generation = len(records) and records[-1]["generation"] + 1
            for point, value in zip(run, means):
                records.append(
                    {"generation": generation, **box.to_dict(point), "mean_return": float(value)}
                )
            values[: len(run)] = means
        return values

    rng = np.random.default_rng(seed)
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
