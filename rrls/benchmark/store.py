"""The result store: tidy tables under ``DIR/results/``, rebuilt from the run directories only.

- ``evaluations``: one row per (run, mesh point, episode) of the final mesh evaluation;
- ``curves``: one row per (run, step) of training returns and periodic evaluations
  (from ``scalars.csv``);
- ``dynamic``: one row per episode of the protagonist against its own adversary (RARL, NR-MDP);
- ``runs``: one row per finished run (worst / average case, dynamic mean, ``source``: ``trained``
  here or ``submitted`` by ``rrls submit``).

A run directory is finished when its ``result.json`` exists (written last, atomically, by
``write_result``); a submitted run's also holds ``submitted`` (where the policy came from).

Every row carries algorithm, task, uncertainty set, seed, steps and the rrls / gymnasium /
mujoco versions. Parquet with pyarrow, CSV without. Rows are sorted, so the same run directories
always give the same files.
"""

from __future__ import annotations

import json
import math
import shlex
from pathlib import Path
from typing import Any

from rrls import files, rundir
from rrls.benchmark.changes import rebuild_folder
from rrls.evaluation import evaldir
from rrls.evaluation.evaldir import DYNAMIC_SCHEMA, EPISODES_SCHEMA
from rrls.physics import ALIASES
from rrls.schema import Schema, TableSchema, integer, number, obj, string
from rrls.seeds import MAX_SEED

TABLES = ("evaluations", "curves", "dynamic", "runs")
KEY = ["algorithm", "task", "uncertainty", "seed"]

_SCORE = number(null=True)  # a split's part without points has no score
#: ``result.json``: every field a run's result may hold, and what it may hold
RESULT_SCHEMA = Schema(
    {
        "algorithm": string(required=True),
        "task": string(required=True),
        "uncertainty": string(required=True),
        "train_set": string(),
        "seed": integer(0, MAX_SEED, required=True),
        "steps": integer(0, 10**12, required=True),
        "physics": string(choices=tuple(ALIASES)),
        "worst_case": number(required=True),
        "average_case": number(required=True),
        "split": string(null=True),
        **{f"{s}_{t}": _SCORE for s in ("worst_case", "average_case") for t in ("id", "ood")},
        "points_id": integer(),
        "points_ood": integer(),
        "dynamic_mean": number(null=True),
        "dynamic_std": number(null=True),
        "dynamic_env": string(),
        "seconds": number(0),
        "versions": obj(Schema({}, open=True)),
        "submitted": obj(Schema({}, open=True)),
        # a run re-evaluated under a newer protocol that trained with other settings than the
        # stored benchmark's (benchmarks/reevaluate.py --keep-training): the ones that differ
        "trained_otherwise": obj(Schema({}, open=True)),
        # the run's identity beyond its directory: the fingerprints of the evaluation protocol
        # and (trained runs) of the benchmark's protocol it ran under
        "protocol": string(),
        "benchmark": string(),
        # the worst case rechecked with fresh episodes, and a low quantile of the point means
        # (``rrls.evaluation.recheck``), with the settings and points it used
        "worst_case_rechecked": number(),
        "worst_case_q": number(),
        "recheck": obj(Schema({}, open=True)),
    }
)
#: ``scalars.csv`` (training curves, long format)
SCALARS_SCHEMA = TableSchema({"step": "int", "metric": "str", "value": "number"}, nan=("value",))


def write_result(run: str | Path, result: dict[str, Any]) -> Path:
    """Mark ``run`` finished: its ``result.json`` (algorithm, task, uncertainty, seed, steps,
    worst_case, average_case, versions; optional dynamic_*, submitted), written atomically and
    sealed (``files.write_checked``)."""
    RESULT_SCHEMA.check(result, "a run result")
    return files.write_checked_json(Path(run) / rundir.RESULT, result)


def read_result(run: str | Path) -> dict[str, Any]:
    """A finished run's ``result.json``, checked against its seal and its schema (one line)."""
    path = Path(run) / rundir.RESULT
    return RESULT_SCHEMA.check(files.read_checked_json(path), str(path))


def _parquet() -> bool:
    try:
        import pyarrow  # noqa: F401
    except ImportError:
        return False
    return True


def _columns(result: dict[str, Any]) -> dict[str, Any]:
    versions = result.get("versions", {})
    return {
        "algorithm": result["algorithm"],
        "task": result["task"],
        "uncertainty": result["uncertainty"],
        "train_set": result.get("train_set", result["uncertainty"]),
        "seed": int(result["seed"]),
        "steps": int(result["steps"]),
        "rrls_version": versions.get("rrls", ""),
        "gymnasium_version": versions.get("gymnasium", ""),
        "mujoco_version": versions.get("mujoco", ""),
    }


def _read_table(base: Path, schema: TableSchema | None = None) -> Any:
    """A run's table (Parquet, else CSV), checked against its seal and its header's schema."""
    path = base.with_suffix(".parquet")
    if not path.exists():
        path = base.with_suffix(".csv")
    frame = files.read_checked_table(path)
    return frame if schema is None else schema.check(frame, str(path))


def _curves(run: Path) -> Any:
    """``scalars.csv`` (step, metric, value) pivoted to one row per step."""
    import pandas as pd

    path = run / rundir.SCALARS
    if not path.exists():
        return pd.DataFrame({"step": []})
    long = SCALARS_SCHEMA.check(files.read_checked_table(path), str(path))
    long["metric"] = long["metric"].str.replace("/", "_", regex=False)
    long["metric"] = long["metric"].str.removeprefix("charts_")
    wide = long.pivot_table(index="step", columns="metric", values="value", aggfunc="last")
    wide.columns.name = None
    return wide.reset_index()


def _check_bound(
    run: Path, result: dict[str, Any], episodes: Any, expected: dict[str, str]
) -> None:
    """A run's files are its own: ``result.json`` names this directory's run and the protocol
    fingerprints of this benchmark (``expected``: ``protocol``, ``benchmark``; a result written
    before fingerprints has none to compare), and the episodes beside it give its scores. A
    seal proves a file intact, not whose it is: a file copied from another run, benchmark or
    protocol (intact, sealed) is refused here, by name."""
    from rrls.benchmark.grid import RunKey
    from rrls.evaluation.metrics import point_means, scores_of

    key = RunKey(str(result["algorithm"]), str(result["task"]), int(result["seed"]))
    own = key.name(str(result["uncertainty"]))
    if own != run.name:
        raise files.DamagedFile(
            f"{run / rundir.RESULT} is the result of run {own}, not of {run.name}: copied from "
            "another run? Re-run or withdraw this one"
        )
    for field, what in (("protocol", "evaluation protocol"), ("benchmark", "benchmark protocol")):
        theirs = result.get(field)
        if theirs is not None and field in expected and theirs != expected[field]:
            raise files.DamagedFile(
                f"{run / rundir.RESULT} was evaluated under another {what} (fingerprint "
                f"{theirs}, this benchmark's {expected[field]}): copied from another benchmark? "
                "Re-run or withdraw this one"
            )
    if not len(episodes):
        return
    for score, value in scores_of(point_means(episodes)).items():
        if not math.isclose(value, float(result[score]), rel_tol=1e-9, abs_tol=1e-9):
            raise files.DamagedFile(
                f"{run / 'eval'}: its episodes give {score} {value:.6g}, but "
                f"{run / rundir.RESULT} says {float(result[score]):.6g}: a file copied from "
                "another run? Re-run or withdraw this one"
            )


def build_store(root: str | Path, expected: dict[str, str] | None = None) -> Path:
    """Scan ``root/runs/*/result.json`` and (re)write ``root/results/*``; returns that folder.
    ``expected``: the benchmark's fingerprints (``protocol``: its evaluation protocol's,
    ``benchmark``: its protocol's), which every run's result must carry when it has them."""
    import pandas as pd

    root = Path(root)
    expected = expected or {}
    frames: dict[str, list[Any]] = {name: [] for name in TABLES}
    for done in sorted((root / "runs").glob("*/result.json")):
        run = done.parent
        result = read_result(run)
        cols = _columns(result)
        episodes = _read_table(run / "eval" / "episodes", EPISODES_SCHEMA)
        episodes = episodes.rename(columns={"seed": "episode_seed"})
        _check_bound(run, result, episodes, expected)
        frames["evaluations"].append(episodes.assign(**cols))
        frames["curves"].append(_curves(run).assign(**cols))
        if (run / evaldir.DYNAMIC).exists():
            path = run / evaldir.DYNAMIC
            dynamic = DYNAMIC_SCHEMA.check(files.read_checked_table(path), str(path))
            dynamic = dynamic.rename(columns={"seed": "episode_seed"})
            frames["dynamic"].append(dynamic.assign(**cols))
        frames["runs"].append(
            pd.DataFrame(
                [
                    {
                        **cols,
                        "worst_case": result["worst_case"],
                        "average_case": result["average_case"],
                        "dynamic_mean": result.get("dynamic_mean"),
                        "worst_case_rechecked": result.get("worst_case_rechecked"),
                        "worst_case_q": result.get("worst_case_q"),
                        "recheck_quantile": (result.get("recheck") or {}).get("quantile"),
                        "source": "submitted" if result.get("submitted") else "trained",
                        "policy_kind": (result.get("submitted") or {}).get("kind"),
                        "policy_source": (result.get("submitted") or {}).get("source"),
                        "policy_sha256": (result.get("submitted") or {}).get("sha256"),
                        "budget": json.dumps((result.get("submitted") or {}).get("budget") or {}),
                        "run_dir": run.name,
                    }
                ]
            )
        )
    return rebuild_folder(root, "results", lambda out: _write_store(out, frames))


def _write_store(out: Path, frames: dict[str, list[Any]]) -> None:
    """Write the store's tables into the new folder ``out`` (swapped in by the caller)."""
    import pandas as pd

    from rrls.files import atomic_write_table

    suffix = ".parquet" if _parquet() else ".csv"
    order = {"evaluations": ["point", "episode"], "curves": ["step"], "dynamic": ["episode"]}
    for name, parts in frames.items():
        frame = pd.concat(parts, ignore_index=True) if parts else pd.DataFrame(columns=KEY)
        keys = ["task", "algorithm", "uncertainty", "seed", *order.get(name, [])]
        if len(frame):
            frame = frame.sort_values(keys, kind="stable").reset_index(drop=True)
        front = [c for c in keys + ["train_set", "steps"] if c in frame.columns]
        frame = frame[front + [c for c in frame.columns if c not in front]]
        atomic_write_table(out / f"{name}{suffix}", frame)


def load_store(root: str | Path) -> dict[str, Any]:
    """The store's tables as DataFrames (``{name: DataFrame}``), reading Parquet or CSV."""
    results = Path(root) / "results"
    if not any((results / f"runs{s}").exists() for s in (".parquet", ".csv")):
        raise FileNotFoundError(
            f"{root} holds no result store (results/runs.parquet or .csv): run `rrls benchmark "
            f"--out {shlex.quote(str(root))}` first"
        )
    return {name: _read_table(results / name) for name in TABLES}
