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

import json
import platform
import warnings
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from rrls.uncertainty import UncertaintySet

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
        """One row per mesh point: its parameters and the mean/std/min return over its episodes."""
        cols = ["point", *self.param_names]
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
        return float(self.per_point["mean_return"].min())

    @property
    def average_case(self) -> float:
        return float(self.per_point["mean_return"].mean())

    @property
    def worst_point(self) -> dict[str, float]:
        """Parameters of the mesh point with the lowest mean return."""
        table = self.per_point
        row = table.loc[table["mean_return"].idxmin()]
        return {name: float(row[name]) for name in self.param_names}

    @property
    def n_diverged(self) -> int:
        return int(self.episodes["diverged"].sum())

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
            **{k: v for k, v in self.config.items() if k not in ("uncertainty",)},
        }

    def save(self, out_dir: str | Path) -> Path:
        """Write ``summary.json`` and ``episodes.parquet`` (``.csv`` without pyarrow) atomically."""
        from rrls._io import atomic_write_json, atomic_write_table

        out_dir = Path(out_dir)
        atomic_write_table(out_dir / _table_name(), self.episodes)
        atomic_write_json(out_dir / "summary.json", self.summary())
        return out_dir

    @classmethod
    def load(cls, out_dir: str | Path) -> EvaluationResult:
        import pandas as pd

        out_dir = Path(out_dir)
        summary_path = out_dir / "summary.json"
        if not summary_path.exists():
            raise FileNotFoundError(f"{out_dir} holds no summary.json: not an rrls evaluation")
        summary = _read_json(summary_path)
        table = out_dir / "episodes.parquet"
        if not table.exists():
            table = out_dir / "episodes.csv"
        try:
            episodes = pd.read_parquet(table) if table.suffix == ".parquet" else pd.read_csv(table)
        except FileNotFoundError:
            raise FileNotFoundError(f"{out_dir} holds no episodes table") from None
        except Exception as err:  # noqa: BLE001 - any unreadable table: name the file
            raise ValueError(f"{table} is unreadable: {err}") from None
        box = summary.get("uncertainty")
        box = UncertaintySet(**box) if box and box.get("names") else None
        config = {k: summary[k] for k in summary if k not in _DERIVED}
        config["uncertainty"] = summary.get("uncertainty")
        return cls(summary["task"], box, episodes, config)

    def __repr__(self) -> str:
        label = self.uncertainty.label if self.uncertainty is not None else f"{self.task}/nominal"
        return (
            f"EvaluationResult({label}: worst_case={self.worst_case:.2f}, "
            f"average_case={self.average_case:.2f}, {len(self.episodes)} episodes)"
        )


_DERIVED = {
    "task",
    "uncertainty",
    "worst_case",
    "average_case",
    "worst_point",
    "points",
    "episodes_total",
    "diverged",
}


def _read_json(path: Path) -> dict[str, Any]:
    """A JSON object from ``path``; a damaged file is named in the error."""
    try:
        data = json.loads(path.read_text())
    except (ValueError, UnicodeDecodeError) as err:
        raise ValueError(
            f"{path} is not valid JSON ({err}); remove it or use another directory"
        ) from None
    if not isinstance(data, dict):
        raise ValueError(f"{path} does not hold a JSON object")
    return data


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
    endpoint: bool = True,
    out_dir: str | Path | None = None,
    batch_size: int | None = None,
    progress: bool | None = None,
    max_episode_steps: int = 1000,
) -> EvaluationResult:
    """Evaluate ``policy`` over a uniform mesh of ``task``'s uncertainty set (paper §4).

    ``policy``: a callable ``obs[B, obs_dim] -> actions[B, act_dim]``, a torch actor, a
    Stable-Baselines3 model, or a saved policy path. ``uncertainty``: ``"1d"``, ``"2d"``, ``"3d"``,
    ``"rarl"`` (forces), ``"nominal"`` (the unmodified model) or an ``UncertaintySet``.
    ``workers`` defaults to every core; results do not depend on it nor on ``batch_size`` (live
    episodes per worker). With ``out_dir``, finished chunks are kept there and a re-run with the
    same arguments resumes; ``summary.json`` and the episode table are written at the end.
    """
    from rrls.envs import resolve
    from rrls.evaluation import runner

    resolved = resolve(task, uncertainty)
    _check_counts(episodes=episodes, nb_mesh_dim=nb_mesh_dim, max_episode_steps=max_episode_steps)
    if workers is not None:
        _check_counts(workers=workers)
    if batch_size is not None:
        _check_counts(batch_size=batch_size)
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ValueError(f"seed must be an integer >= 0, got {seed!r}")
    points = resolved.box.mesh(nb_mesh_dim, endpoint=endpoint)
    seeds = runner.episode_seeds(seed, len(points), episodes)
    spec = runner.RolloutSpec(
        resolved.task, resolved.family, resolved.box.names, points, seeds, max_episode_steps
    )
    settings = {
        "mesh": nb_mesh_dim,
        "endpoint": endpoint,
        "episodes": episodes,
        "seed": seed,
        "max_episode_steps": max_episode_steps,
    }
    try:  # the engine's env cache lives only as long as this evaluation
        return _evaluate(policy, resolved, spec, settings, workers, batch_size, out_dir, progress)
    finally:
        runner.clear_env_cache()


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
) -> EvaluationResult:
    from rrls.evaluation import runner
    from rrls.evaluation.policies import as_policy, policy_fingerprint

    key, kind = resolved.task, resolved.family
    box = None if resolved.is_nominal else resolved.box
    policy = as_policy(policy)
    trained_on = (getattr(policy, "metadata", None) or {}).get("task")
    if trained_on is not None and trained_on != key:
        raise ValueError(f"the policy was trained on {trained_on!r}, not on task {key!r}")
    policy, obs_dim = prepare_policy(policy, spec)

    config = {
        "uncertainty": _box_json(box),
        "uncertainty_name": resolved.name or resolved.label,
        "env": f"rrls/{kind}-{key}-v0",
        **settings,
        "chunk": runner.CHUNK,
        "policy_fingerprint": policy_fingerprint(policy, obs_dim),
    }
    if out_dir is None:
        frame = rollout_table(spec, policy, workers, batch_size, None, progress)
        return _finish(key, box, frame, config, policy)
    from rrls._io import DirectoryLock

    with DirectoryLock(Path(out_dir)):  # one evaluation at a time per directory
        chunk_dir = _prepare_out_dir(Path(out_dir), config)
        frame = rollout_table(spec, policy, workers, batch_size, chunk_dir, progress)
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
) -> Any:
    """Run ``spec`` through the engine: one DataFrame row per (point, episode)."""
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
