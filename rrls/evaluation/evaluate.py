"""``evaluate``: the paper's robust evaluation (§4): mesh, episodes per point, worst/average case.

>>> import numpy as np
>>> from rrls.evaluation import evaluate
>>> still = lambda obs: np.zeros((len(obs), 1))  # push nothing: the pole falls
>>> result = evaluate(still, "invertedpendulum", "1d", nb_mesh_dim=3, episodes=2, workers=1)
>>> result.episodes[["polemass", "episode", "length"]].shape
(6, 3)
>>> result.worst_case <= result.average_case
True
"""

from __future__ import annotations

import platform
import warnings
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from rrls.evaluation.metrics import SCORES, scores_of
from rrls.physics import physics_label
from rrls.uncertainty import Split, UncertaintySet

EPISODE_COLUMNS = ("point", "episode", "seed", "return", "length", "terminated", "diverged")


@dataclass
class EvaluationResult:
    """Per-episode table plus the paper's two numbers.

    ``worst_case`` is the minimum over mesh points of the mean return over that point's episodes,
    ``average_case`` the mean over points of that same per-point mean.
    """

    task: str
    uncertainty: UncertaintySet | None
    episodes: Any  # pandas.DataFrame, one row per (point, episode)
    config: dict[str, Any] = field(default_factory=dict)

    @property
    def param_names(self) -> list[str]:
        return list(self.uncertainty.names) if self.uncertainty is not None else []

    @property
    def per_point(self) -> Any:
        """One row per mesh point: its parameters and the mean/std/min return over its episodes
        (and ``in_distribution`` when the evaluation was given a split)."""
        cols = ["point", *self.param_names]
        if "in_distribution" in self.episodes:
            cols.append("in_distribution")
        grouped = self.episodes.groupby(cols, sort=True)["return"]
        table = grouped.agg(["mean", "std", "min", "count"]).reset_index()
        return table.rename(
            columns={
                "mean": "mean_return",
                "std": "std_return",
                "min": "min_return",
                "count": "episodes",
            }
        )

    @property
    def worst_case(self) -> float:
        return scores_of(self.per_point["mean_return"])["worst_case"]

    @property
    def average_case(self) -> float:
        return scores_of(self.per_point["mean_return"])["average_case"]

    @property
    def worst_point(self) -> dict[str, float]:
        """Parameters of the mesh point with the lowest mean return."""
        table = self.per_point
        row = table.loc[table["mean_return"].idxmin()]
        return {name: float(row[name]) for name in self.param_names}

    @property
    def n_diverged(self) -> int:
        return int(self.episodes["diverged"].sum())

    def split_scores(self) -> dict[str, float | int | None]:
        """Worst and average case over the in-distribution (training part) and the
        out-of-distribution (test part) mesh points separately; empty without a split."""
        if "in_distribution" not in self.episodes:
            return {}
        table = self.per_point
        out: dict[str, float | int | None] = {}
        for tag, mask in (("id", table["in_distribution"]), ("ood", ~table["in_distribution"])):
            means = table.loc[mask, "mean_return"]
            scores = scores_of(means) if len(means) else {}
            for score in SCORES:
                out[f"{score}_{tag}"] = scores.get(score)
            out[f"points_{tag}"] = int(mask.sum())
        return out

    def summary(self) -> dict[str, Any]:
        """What ``summary.json`` holds."""
        return {
            "task": self.task,
            "uncertainty": self.config.get("uncertainty"),
            "worst_case": self.worst_case,
            "average_case": self.average_case,
            "worst_point": self.worst_point,
            "points": int(self.episodes["point"].nunique()),
            "episodes_total": len(self.episodes),
            "diverged": self.n_diverged,
            **self.split_scores(),
            **{k: v for k, v in self.config.items() if k not in ("uncertainty",)},
        }

    def save(self, out_dir: str | Path) -> Path:
        """Write ``summary.json`` and ``episodes.parquet`` (``.csv`` without pyarrow) atomically."""
        from rrls.rundir import write_checked_json, write_checked_table

        out_dir = Path(out_dir)
        write_checked_table(out_dir / _table_name(), self.episodes)  # sealed: damage is seen
        write_checked_json(out_dir / "summary.json", self.summary())
        return out_dir

    @classmethod
    def load(cls, out_dir: str | Path) -> EvaluationResult:
        from rrls.rundir import read_checked_table

        out_dir = Path(out_dir)
        summary_path = out_dir / "summary.json"
        if not summary_path.exists():
            raise FileNotFoundError(f"{out_dir} holds no summary.json: not an rrls evaluation")
        summary = _read_json(summary_path)
        table = out_dir / "episodes.parquet"
        if not table.exists():
            table = out_dir / "episodes.csv"
        try:
            episodes = read_checked_table(table)  # a damaged table: one line naming it
        except FileNotFoundError:
            raise FileNotFoundError(f"{out_dir} holds no episodes table") from None
        box = summary.get("uncertainty")
        box = UncertaintySet(**box) if box and box.get("names") else None
        config = {k: summary[k] for k in summary if k not in _DERIVED}
        config["uncertainty"] = summary.get("uncertainty")
        return cls(summary["task"], box, episodes, config)

    def __repr__(self) -> str:
        label = self.uncertainty.label if self.uncertainty is not None else f"{self.task}/nominal"
        split = self.split_scores()
        extra = (
            f", ID worst/average={_fmt(split['worst_case_id'])}/{_fmt(split['average_case_id'])}"
            f", OOD worst/average={_fmt(split['worst_case_ood'])}/"
            f"{_fmt(split['average_case_ood'])}"
            if split
            else ""
        )
        return (
            f"EvaluationResult({label}: worst_case={self.worst_case:.2f}, "
            f"average_case={self.average_case:.2f}{extra}, {len(self.episodes)} episodes)"
        )


def _fmt(value: float | None) -> str:
    return "-" if value is None else f"{value:.2f}"


_DERIVED = {
    "task",
    "uncertainty",
    "worst_case",
    "average_case",
    "worst_point",
    "points",
    "episodes_total",
    "diverged",
    *(f"{m}_{t}" for m in ("worst_case", "average_case", "points") for t in ("id", "ood")),
}


def _read_json(path: Path) -> dict[str, Any]:
    """A JSON object from ``path``; a damaged file is named in the error."""
    from rrls.rundir import read_checked_json

    return read_checked_json(path)


def _table_name() -> str:
    try:
        import pyarrow  # noqa: F401
    except ImportError:
        return "episodes.csv"
    return "episodes.parquet"


def versions() -> dict[str, str]:
    import gymnasium
    import mujoco

    from rrls import __version__

    return {
        "rrls": __version__,
        "gymnasium": gymnasium.__version__,
        "mujoco": mujoco.__version__,
        "numpy": np.__version__,
        "python": platform.python_version(),
    }


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


def evaluate(
    policy: Any,
    task: str,
    uncertainty: str | UncertaintySet = "3d",
    nb_mesh_dim: int = 10,
    episodes: int = 5,
    seed: int = 0,
    workers: int | None = None,
    *,
    endpoint: bool | None = None,
    out_dir: str | Path | None = None,
    batch_size: int | None = None,
    progress: bool | None = None,
    max_episode_steps: int | None = None,
    disruptors: Mapping[str, float | Sequence[float]] | None = None,
    schedule: Any = None,
    context: bool = False,
    split: Split | None = None,
    paper: bool = False,
    view: Any = None,
) -> EvaluationResult:
    """Evaluate ``policy`` over a uniform mesh of ``task``'s uncertainty set (paper §4).

    ``policy``: a callable ``obs[B, obs_dim] -> actions[B, act_dim]``, a torch actor, a
    Stable-Baselines3 model, or a saved policy path. ``uncertainty``: ``"1d"``, ``"2d"``, ``"3d"``,
    ``"rarl"`` (forces), ``"nominal"`` (the unmodified model) or an ``UncertaintySet``.
    ``workers`` defaults to every core; results do not depend on it nor on ``batch_size`` (live
    episodes per worker). With ``out_dir``, finished chunks are kept there and a re-run with the
    same arguments resumes; ``summary.json`` and the episode table are written at the end.
    ``max_episode_steps`` defaults to the task's episode length (1000 for the paper's tasks).
    ``paper=True`` runs the paper's protocol on the paper's physics: the Gymnasium v4 envs with
    the original code's parameter writes (:mod:`rrls.envs.paper`), and (unless ``endpoint`` says
    otherwise) the original code's ``np.arange`` mesh, which stops short of the upper bounds. The
    default is Gymnasium v5 with rrls's parameter semantics and a mesh reaching both bounds;
    ``summary.json`` records which (``physics``).

    Beyond static dynamics (the README section of that name):

    * a set may name disruptor strengths (``obsnoise``, ``actiondelay``...: see
      :mod:`rrls.wrappers.disruptors`) alone or with physical parameters; ``disruptors`` adds
      some: ``{"obsnoise": 0.05}`` a fixed strength, ``{"obsnoise": (0, 0.1)}`` a meshed axis;
    * ``schedule``: a :class:`~rrls.wrappers.ScheduleFamily`; the mesh is then its grid (e.g.
      drift rate x direction) and the set is where the schedule moves, from its nominal point;
    * ``context=True`` appends the set's normalised parameters to the observation (a policy
      trained with :class:`~rrls.wrappers.ContextObservation`);
    * ``split``: a :class:`~rrls.uncertainty.Split` of the set; rows get ``in_distribution`` and
      the result the worst/average case in and out of distribution;
    * ``view``: what a TC-RMDP Stacked or Oracle protagonist observes
      (:class:`~rrls.wrappers.tc_rmdp.View`); by default the one the policy's metadata records
      (``rrls train --algo rarl --rate-limit R --observe ...``), so it sees what it trained on.

    Rows stay equal to the one-episode loop on the same wrapper stack
    (``env.set_params(**point); env.reset(seed=seed)``).
    """
    from rrls.envs import paper_class
    from rrls.evaluation import runner
    from rrls.evaluation.policies import as_policy
    from rrls.evaluation.stack import policy_view
    from rrls.tasks import get_task

    policy = as_policy(policy)
    if view is None:
        view = policy_view(policy)
    mesh_box, resolved, stack = _plan(task, uncertainty, disruptors, schedule, context, view)
    if max_episode_steps is None:
        max_episode_steps = get_task(resolved.task).max_episode_steps
    if endpoint is None:
        endpoint = not paper
    if paper:
        paper_class(resolved.env_class)  # a task without paper physics: refused now
    _check_counts(episodes=episodes, nb_mesh_dim=nb_mesh_dim, max_episode_steps=max_episode_steps)
    if workers is not None:
        _check_counts(workers=workers)
    if batch_size is not None:
        _check_counts(batch_size=batch_size)
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ValueError(f"seed must be an integer >= 0, got {seed!r}")
    if schedule is None:
        points = mesh_box.mesh(nb_mesh_dim, endpoint=endpoint)
    else:
        points = _product(
            schedule.points(), _ranged(mesh_box, schedule).mesh(nb_mesh_dim, endpoint)
        )
    _check_strengths(mesh_box, points)
    seeds = runner.episode_seeds(seed, len(points), episodes)
    spec = runner.RolloutSpec(
        resolved.task,
        resolved.family,
        mesh_box.names,
        points,
        seeds,
        max_episode_steps,
        None if stack.empty else stack,
        paper=bool(paper),
    )
    settings = {
        "physics": physics_label(bool(paper)),
        "mesh": nb_mesh_dim,
        "endpoint": endpoint,
        "episodes": episodes,
        "seed": seed,
        "max_episode_steps": max_episode_steps,
        **stack.to_json(),
    }
    if schedule is not None:  # what was meshed: the family's grid
        settings["schedule"] = schedule.to_json()
    if split is not None:
        in_dist = _split_mask(split, mesh_box, points, schedule)
        settings["split"] = split.to_json()
    else:
        in_dist = None
    try:  # the engine's env cache lives only as long as this evaluation
        return _evaluate(
            policy,
            resolved,
            spec,
            settings,
            workers,
            batch_size,
            out_dir,
            progress,
            mesh_box,
            in_dist,
        )
    finally:
        runner.clear_env_cache()


def _plan(
    task: str,
    uncertainty: str | UncertaintySet,
    disruptors: Mapping[str, float | Sequence[float]] | None,
    schedule: Any,
    context: bool,
    view: Any = None,
) -> tuple[UncertaintySet, Any, Any]:
    """(the box of the mesh's names, the resolved physical set, the wrapper stack).

    The mesh's names are the set's (physical ones first resolved as usual, disruptor strengths
    kept) plus the meshed ``disruptors``; under a ``schedule`` the schedule's fields come first.
    """
    from rrls.envs import resolve
    from rrls.evaluation.stack import EnvStack
    from rrls.wrappers import DISRUPTORS, ScheduleFamily

    fixed: dict[str, float] = {}
    ranged: dict[str, tuple[float, float]] = {}
    if isinstance(uncertainty, UncertaintySet) and set(uncertainty.names) & set(DISRUPTORS):
        box = uncertainty
        names = [n for n in box.names if n not in DISRUPTORS]
        for n, lo, hi in zip(box.names, box.low, box.high):
            if n in DISRUPTORS:
                ranged[n] = (float(lo), float(hi))
        physical = (
            UncertaintySet(
                tuple(names),
                [box.low[box.names.index(n)] for n in names],
                [box.high[box.names.index(n)] for n in names],
                None if box.nominal is None else [box.nominal[box.names.index(n)] for n in names],
                box.label,
                box.family,
            )
            if names
            else "nominal"
        )
    else:
        physical = uncertainty
    for name, value in dict(disruptors or {}).items():
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
    for name, (lo, hi) in ranged.items():
        for v in (lo, hi):
            problem = DISRUPTORS[name].check_param(name, v)
            if problem:
                raise ValueError(problem)
    for name, v in fixed.items():
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


def _check_counts(**values: Any) -> None:
    """Refuse counts below 1 (and non-integers), naming the argument."""
    for name, value in values.items():
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
            raise ValueError(f"{name} must be an integer >= 1, got {value!r}")


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
    from rrls.evaluation import runner
    from rrls.evaluation.policies import as_policy, policy_fingerprint

    key, kind = resolved.task, resolved.family
    box = None if mesh_box.dim == 0 else mesh_box
    policy = as_policy(policy)
    trained_on = (getattr(policy, "metadata", None) or {}).get("task")
    if trained_on is not None and trained_on != key:
        raise ValueError(f"the policy was trained on {trained_on!r}, not on task {key!r}")
    policy, obs_dim = prepare_policy(policy, spec)

    config = {
        "uncertainty": _box_json(box),
        "uncertainty_name": resolved.name or resolved.label,
        "env": f"rrls/{kind}-{key}-v0" + (" (paper=True)" if spec.paper else ""),
        **settings,
        "chunk": runner.CHUNK,
        "policy_fingerprint": policy_fingerprint(policy, obs_dim),
    }
    if out_dir is None:
        frame = rollout_table(spec, policy, workers, batch_size, None, progress, in_dist)
        return _finish(key, box, frame, config, policy)
    from rrls._io import DirectoryLock

    with DirectoryLock(Path(out_dir)):  # one evaluation at a time per directory
        chunk_dir = _prepare_out_dir(Path(out_dir), config)
        frame = rollout_table(spec, policy, workers, batch_size, chunk_dir, progress, in_dist)
        result = _finish(key, box, frame, config, policy)
        result.save(out_dir)
    return result


def _finish(
    key: str, box: UncertaintySet | None, frame: Any, config: dict[str, Any], policy: Any
) -> EvaluationResult:
    config["versions"] = versions()
    config.update(_policy_record(policy))
    result = EvaluationResult(key, box, frame, config)
    if result.n_diverged:
        warnings.warn(
            f"{result.n_diverged} episode(s) diverged (MuJoCo instability); they are kept with "
            "the return reached before the divergence and flagged in the 'diverged' column",
            stacklevel=4,
        )
    return result


def _policy_record(policy: Any) -> dict[str, Any]:
    """What ``summary.json`` says of the policy: its algorithm, training seed and run directory."""
    meta = getattr(policy, "metadata", None) or {}
    record = {
        "policy_algorithm": meta.get("algorithm"),
        "policy_seed": meta.get("seed"),
        "policy_run_dir": meta.get("run_dir"),
        "policy_path": meta.get("path"),
    }
    return {k: v for k, v in record.items() if v is not None}


def prepare_policy(policy: Any, spec: Any) -> tuple[Callable[[np.ndarray], Any], int]:
    """Adapt ``policy``, check it against the task's spaces, warn if it is not batch-invariant."""
    from rrls.evaluation.policies import as_policy, is_batch_invariant

    policy = as_policy(policy)
    obs_dim, act_dim = _dims(spec)
    _check_policy(policy, obs_dim, act_dim)
    if not is_batch_invariant(policy, obs_dim):
        warnings.warn(
            "the policy's actions depend on the batch size (BLAS kernels differ), so results may "
            "differ in the last bits from a one-episode-at-a-time loop; wrap it in "
            "rrls.evaluation.BatchInvariant(policy) for exact equality",
            stacklevel=3,
        )
    return policy, obs_dim


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

    from rrls.evaluation import runner

    cols = runner.run(
        spec,
        policy,
        workers=workers,
        lanes=batch_size or runner.LANES,
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


def _dims(spec: Any) -> tuple[int, int]:
    from rrls.evaluation.runner import make_rollout_envs

    env = make_rollout_envs(spec, 1)[0]
    return env.observation_space.shape[0], env.action_space.shape[0]


def _check_policy(policy: Callable, obs_dim: int, act_dim: int) -> None:
    """Fail before any rollout if the policy cannot map observations to actions."""
    from rrls.evaluation.runner import PolicyError

    try:
        out = np.asarray(policy(np.zeros((2, obs_dim))))
    except Exception as err:
        raise PolicyError(
            f"calling the policy on a batch of observations of shape (2, {obs_dim}) failed: {err}"
        ) from err
    if out.dtype.kind not in "biuf":
        raise PolicyError(f"the policy returned {out.dtype} values; actions must be real numbers")
    if out.shape != (2, act_dim):
        raise PolicyError(
            f"the policy maps observations (2, {obs_dim}) to shape {out.shape}; expected "
            f"(2, {act_dim}) for this task"
        )


def _prepare_out_dir(out_dir: Path, config: dict[str, Any]) -> Path:
    """Create ``out_dir`` or check that it holds a run with the same arguments (to resume it)."""
    from rrls._io import atomic_write_json

    path = out_dir / "evaluation.json"
    if path.exists():
        old = _read_json(path)
        diff = sorted(k for k in set(old) | set(config) if old.get(k) != config.get(k))
        if diff:
            raise ValueError(
                f"{out_dir} holds an evaluation with different arguments ({', '.join(diff)}); "
                "use another output directory or the same arguments to resume"
            )
    else:
        atomic_write_json(path, config)
    return out_dir / "chunks"
