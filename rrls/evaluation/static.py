"""``evaluate``: the paper's robust evaluation (§4): mesh, episodes per point, worst/average case.

>>> import numpy as np
>>> from rrls.evaluation import Protocol, evaluate
>>> still = lambda obs: np.zeros((len(obs), 1))  # push nothing: the pole falls
>>> result = evaluate(still, "invertedpendulum", Protocol("1d", mesh=3, episodes=2), workers=1)
>>> result.episodes[["polemass", "episode", "length"]].shape
(6, 3)
>>> result.worst_case <= result.average_case
True
"""

from __future__ import annotations

import warnings
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from rrls.deprecation import renamed_keywords
from rrls.evaluation import engine, evaldir, lanes
from rrls.evaluation.chunks import CHUNK
from rrls.evaluation.defaults import Default, keyword_protocol
from rrls.evaluation.prepared import PreparedPolicy, policy_record, prepare_policy
from rrls.evaluation.protocol import Protocol, check_sizes
from rrls.evaluation.result import EvaluationResult
from rrls.provenance import versions
from rrls.uncertainty import Split, UncertaintySet


def _box_json(box: UncertaintySet | None) -> dict[str, Any] | None:
    if box is None:
        return None
    return {
        "names": list(box.names),
        "low": box.low.tolist(),
        "high": box.high.tolist(),
        "nominal": None if box.nominal is None else box.nominal.tolist(),
        "label": box.label,
    }


@renamed_keywords(nb_mesh_dim="mesh")
def evaluate(
    policy: Any,
    task: str,
    protocol: Protocol | str | UncertaintySet | None = None,
    mesh: int | Default = Default(10),
    episodes: int | Default = Default(5),
    seed: int | Default = Default(0),
    workers: int | None = None,
    *,
    out_dir: str | Path | None = None,
    batch_size: int | None = None,
    progress: bool | None = None,
    view: Any = None,
    uncertainty: str | UncertaintySet | Default = Default("3d"),
    endpoint: bool | None | Default = Default(None),
    max_episode_steps: int | None | Default = Default(None),
    disruptors: Mapping[str, float | Sequence[float]] | None | Default = Default(None),
    schedule: Any = Default(None),
    context: bool | Default = Default(False),
    split: Split | None | Default = Default(None),
    paper: bool | Default = Default(False),
) -> EvaluationResult:
    """Evaluate ``policy`` on ``task`` under ``protocol`` (paper §4): a uniform mesh of the
    protocol's uncertainty set, its episodes per point, the worst and average case.

    ``policy``: a callable ``obs[B, obs_dim] -> actions[B, act_dim]``, a torch actor, a
    Stable-Baselines3 model, a saved policy path, or a policy prepared once for several
    evaluations (:func:`~rrls.evaluation.prepare`). ``protocol``: a
    :class:`~rrls.evaluation.Protocol`, which holds everything that decides the numbers (the
    set, mesh, episodes, seed, physics, split, disruptors, schedule, context: see its fields and
    docs/perturbations.md), as a benchmark stores it.

    How it runs changes no number: ``workers`` (processes; default every core) and
    ``batch_size`` (live episodes per worker). With ``out_dir``, finished chunks are kept there
    and a re-run with the same arguments resumes; ``summary.json`` and the episode table are
    written at the end. ``view``: what a TC-RMDP Stacked or Oracle protagonist observes
    (:class:`~rrls.wrappers.tc_rmdp.View`); by default the one the policy's metadata records,
    so it sees what it trained on.

    For interactive use the protocol's fields may be given as keywords instead, which build the
    protocol (:func:`~rrls.evaluation.defaults.keyword_protocol`): ``uncertainty`` (also the
    third argument: ``"1d"``, ``"2d"``, ``"3d"``, ``"rarl"``, ``"nominal"`` or an
    ``UncertaintySet``), ``mesh``, ``episodes``, ``seed``, ``endpoint``, ``max_episode_steps``,
    ``disruptors`` (``{"obsnoise": 0.05}`` fixed, ``{"obsnoise": (0, 0.1)}`` meshed),
    ``schedule``, ``context``, ``split``, and ``paper=True`` for the paper's physics. Defaults
    (``Protocol()``'s): the ``"3d"`` set, ``mesh=10`` points per dimension, ``episodes=5`` per
    point, ``seed=0``, the v5 physics (``paper=False``), no split, disruptor, schedule or
    context. Passing any of them beside a protocol is an error naming them (whatever the value:
    ``mesh=10`` too, as the protocol's would win).

    Rows stay equal to the one-episode loop on the same wrapper stack
    (``env.set_params(**point); env.reset(seed=seed)``).
    """
    from rrls.evaluation.policies import as_policy
    from rrls.evaluation.stack import policy_view

    if isinstance(protocol, (str, UncertaintySet)):  # the set in third place: a keyword call
        if not isinstance(uncertainty, Default):
            raise TypeError("evaluate() got the set twice: as its third argument and uncertainty=")
        protocol, uncertainty = None, protocol
    protocol = keyword_protocol(
        "evaluate",
        protocol,
        {
            "uncertainty": uncertainty,
            "mesh": mesh,
            "episodes": episodes,
            "seed": seed,
            "endpoint": endpoint,
            "max_episode_steps": max_episode_steps,
            "disruptors": disruptors,
            "schedule": schedule,
            "context": context,
            "split": split,
            "paper": paper,
        },
    )
    if not isinstance(policy, PreparedPolicy):  # prepared at the door: adapted already
        policy = as_policy(policy)
    if view is None:
        view = policy_view(policy)
    plan = protocol.plan(task, view)
    if workers == 0:  # 0: in this process, as every rrls command reads it (= one worker)
        workers = 1
    check_sizes(workers=workers, batch_size=batch_size)
    spec = lanes.Rollouts.from_plan(plan, protocol)
    try:  # the engine's env cache lives only as long as this evaluation
        return _evaluate(
            policy,
            plan.resolved,
            spec,
            dict(plan.settings),
            workers,
            batch_size,
            out_dir,
            progress,
            plan.mesh_box,
            plan.in_distribution,
        )
    finally:
        lanes.clear_env_cache()


def _evaluate(
    policy: Any,
    resolved: Any,
    spec: Any,
    settings: dict[str, Any],
    workers: int | None,
    batch_size: int | None,
    out_dir: str | Path | None,
    progress: bool | None,
    mesh_box: UncertaintySet,
    in_dist: np.ndarray | None,
) -> EvaluationResult:
    key, kind = resolved.task, resolved.family
    box = None if mesh_box.dim == 0 else mesh_box
    policy = prepare_policy(policy, spec, stacklevel=4)
    fingerprint = policy.fingerprint

    config = {
        "uncertainty": _box_json(box),
        "uncertainty_name": resolved.name or resolved.label,
        "env": f"rrls/{kind}-{key}-v0" + (" (paper=True)" if spec.paper else ""),
        **settings,
        "chunk": CHUNK,
        "policy_fingerprint": fingerprint,
    }
    if out_dir is None:
        frame = rollout_table(spec, policy, workers, batch_size, None, progress, in_dist)
        return _finish(key, box, frame, config, policy)
    with evaldir.opened(out_dir, config) as chunk_dir:  # one evaluation at a time per directory
        frame = rollout_table(spec, policy, workers, batch_size, chunk_dir, progress, in_dist)
        result = _finish(key, box, frame, config, policy)
        result.save(out_dir)
    return result


def _finish(
    key: str, box: UncertaintySet | None, frame: Any, config: dict[str, Any], policy: Any
) -> EvaluationResult:
    config["versions"] = versions()
    config.update(policy_record(policy))
    result = EvaluationResult(key, box, frame, config)
    if result.n_diverged:
        warnings.warn(
            f"{result.n_diverged} episode(s) diverged (MuJoCo instability); they are kept with "
            "the return reached before the divergence and flagged in the 'diverged' column",
            stacklevel=4,
        )
    return result


def rollout_table(
    spec: Any,
    policy: Callable[[np.ndarray], Any],
    workers: int | None = None,
    batch_size: int | None = None,
    chunk_dir: Path | None = None,
    progress: bool | None = False,
    in_distribution: np.ndarray | None = None,
) -> Any:
    """Run ``spec`` through the engine: one DataFrame row per (point, episode); with
    ``in_distribution`` (one flag per point), a column of it."""
    import pandas as pd

    cols = engine.run(
        spec,
        policy,
        workers=workers,
        lanes=batch_size or lanes.LANES,
        chunk_dir=chunk_dir,
        progress=progress,
    )
    episodes = spec.seeds.shape[1]
    point_idx, episode_idx = np.divmod(np.arange(spec.n_episodes), episodes)
    table: dict[str, Any] = {"point": point_idx}
    for i, name in enumerate(spec.names):
        table[name] = spec.points[point_idx, i]
    if in_distribution is not None:
        table["in_distribution"] = np.asarray(in_distribution, dtype=bool)[point_idx]
    table.update(episode=episode_idx, seed=spec.seeds.reshape(-1).astype(np.int64), **cols)
    return pd.DataFrame(table)


class Evaluator:
    """A protocol planned once for a task and run for many policies: training's periodic
    evaluation. ``evaluate()`` checks, fingerprints and records each policy and rebuilds its
    envs every call; a run evaluating its own ``MLPPolicy`` every few thousand steps needs none
    of that, only the same rows (``evaluate``'s, bit for bit: the same plan, seeds and engine).
    The envs stay cached between calls until ``close()``.
    """

    def __init__(self, task: str, protocol: Protocol, view: Any = None) -> None:
        self.plan = protocol.plan(task, view)
        self.spec = lanes.Rollouts.from_plan(self.plan, protocol)

    def __call__(self, policy: Callable[[np.ndarray], Any]) -> EvaluationResult:
        """``policy``'s rows on one worker (``policy``: batch-invariant, e.g. ``MLPPolicy``)."""
        frame = rollout_table(self.spec, policy, 1, None, None, False, self.plan.in_distribution)
        box = None if self.plan.mesh_box.dim == 0 else self.plan.mesh_box
        return EvaluationResult(self.spec.task, box, frame, dict(self.plan.settings))

    def close(self) -> None:
        lanes.clear_env_cache()


__all__ = ["Evaluator", "evaluate", "rollout_table"]
