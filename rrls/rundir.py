"""The run directory: the one module that knows its file names and formats.

``rrls train`` writes, ``rrls evaluate``, the dynamic evaluation, the benchmark pipeline and its
store read::

    RUN/checkpoint.pt    learner state + generators (torch, weights_only), sealed by a SHA-256
    RUN/policy.npz       the final policy (``MLPPolicy``: arrays + JSON header, no pickle)
    RUN/adversary.npz    the final adversary of two-player runs (RARL, NR-/PR-MDP)
    RUN/run.json         metadata, configuration, hyper-parameters, steps: the run is finished
    RUN/scalars.csv      training curves ``step,metric,value``
    RUN/tb/              TensorBoard events
    RUN/result.json      (benchmark) evaluation summary: the run is done
    RUN/progress.json    (benchmark) phase and step, read by the driver
    RUN/error.txt        (benchmark) the traceback of a failed stage

No torch here: the sealed checkpoint is bytes in, bytes out.

How the files are written and read back (atomically; sealed by their SHA-256, so damage is a
one-line ``DamagedFile``, never numbers) is ``rrls.files``'s; this module says which files a run
holds and what is in them.
"""

from __future__ import annotations

import shutil
from pathlib import Path
from typing import Any

from rrls.files import (
    DAMAGE_ADVICE,
    DamagedFile,
    read_checked_json,
    seal_path,
    sealed_prefix,
    write_checked,
)
from rrls.physics import ALIASES
from rrls.schema import Schema, SchemaError, array, integer, obj, string
from rrls.seeds import MAX_SEED

CHECKPOINT = "checkpoint.pt"
POLICY = "policy.npz"
ADVERSARY = "adversary.npz"
RUN_JSON = "run.json"
SCALARS = "scalars.csv"
TENSORBOARD = "tb"
RESULT = "result.json"
PROGRESS = "progress.json"
ERROR = "error.txt"
#: what a fresh start or ``--overwrite`` removes
RUN_FILES = (CHECKPOINT, POLICY, ADVERSARY, RUN_JSON, SCALARS)

_OPEN = Schema({}, open=True)
#: ``run.json``: the policy's metadata (open: an algorithm may add its own), the run's settings
#: (``config``, its ``hyper`` every resolved hyper-parameter; files written before hold the
#: resolved ones as ``hyperparameters`` beside it: ``migrate_run_json``), the run's summary;
#: the fields rrls reads are typed
RUN_SCHEMA = Schema(
    {
        "algorithm": string(required=True),
        "task": string(),
        "uncertainty": string(null=True),
        "seed": integer(0, MAX_SEED),
        "steps": integer(0, 10**12, required=True),
        "episodes": integer(),
        "obs_dim": integer(1),
        "act_dim": integer(1),
        "hidden": array(integer(1), max_items=64),
        "physics": string(choices=tuple(ALIASES)),
        "config": obj(_OPEN),
        "hyperparameters": obj(_OPEN),
        "provenance": obj(_OPEN),
        "versions": obj(_OPEN),
    },
    open=True,
)


def read_run_json(run_dir: Path) -> dict[str, Any]:
    """A finished training run's ``run.json``, checked against its schema, in today's form
    (``migrate_run_json``): a damaged or foreign file is a one-line ``DamagedFile`` naming it
    (``FileNotFoundError`` if absent)."""
    path = Path(run_dir) / RUN_JSON
    try:
        return migrate_run_json(RUN_SCHEMA.check(read_checked_json(path), str(path)))
    except SchemaError as err:
        raise DamagedFile(f"{err} ({DAMAGE_ADVICE})") from None


def migrate_run_json(data: dict[str, Any]) -> dict[str, Any]:
    """``run.json`` in today's form: the run's settings once, under ``config``, its ``hyper``
    every resolved hyper-parameter. A file written before (``config.hyper`` held only the
    overrides, ``hyperparameters`` beside it the resolved ones) reads as the same run."""
    if "hyperparameters" not in data:
        return data
    out = {k: v for k, v in data.items() if k != "hyperparameters"}
    out["config"] = {**(data.get("config") or {}), "hyper": data["hyperparameters"]}
    return out


def executions(run: dict[str, Any]) -> list[dict[str, Any]]:
    """The processes that trained a run, in order, each with its ``machine`` and ``commit``
    (``None`` where unknown): ``run.json``'s ``provenance.executions``; a ``run.json`` from
    before executions were recorded gives one, its last execution's."""
    provenance = run.get("provenance") or {}
    listed = provenance.get("executions")
    if isinstance(listed, list) and listed:
        return [e if isinstance(e, dict) else {} for e in listed]
    return [{"machine": provenance.get("machine"), "commit": provenance.get("commit")}]


def finished_steps(run_dir: Path) -> int | None:
    """The steps of the finished run in ``run_dir`` (policy and a valid run.json), else None:
    a run whose ``run.json`` is damaged is not finished (it trains again)."""
    if not (run_dir / POLICY).exists():
        return None
    try:
        return int(read_run_json(run_dir)["steps"])
    except (OSError, ValueError):
        return None


def remove_run_files(run_dir: Path) -> None:
    """What a previous run left (its checkpoint, policies, logs)."""
    for name in RUN_FILES:
        (run_dir / name).unlink(missing_ok=True)
        seal_path(run_dir / name).unlink(missing_ok=True)
    shutil.rmtree(run_dir / TENSORBOARD, ignore_errors=True)


def remove_temporary_files(run_dir: Path) -> None:
    """Temporary files of atomic writes killed half-way (``.checkpoint.pt.XXXX.tmp``)."""
    for path in run_dir.glob(".*.tmp"):
        path.unlink(missing_ok=True)


def truncate_scalars(path: Path, step: int) -> None:
    """Drop curve rows written after the checkpoint being resumed (they will be redone);
    damaged rows are a one-line ``DamagedFile`` naming the file."""
    if not path.exists():
        return
    data = sealed_prefix(path, path.read_bytes())
    try:
        lines = data.decode("utf-8").splitlines(keepends=True)
        rows = [ln for ln in lines[1:] if ln.endswith("\n") and int(ln.split(",", 1)[0]) <= step]
    except ValueError as err:  # not UTF-8, or a step that is no integer
        raise DamagedFile(f"{path} is damaged ({err}); {DAMAGE_ADVICE}") from None
    write_checked(path, "".join(lines[:1] + rows).encode())


__all__ = [
    "ADVERSARY",
    "CHECKPOINT",
    "ERROR",
    "POLICY",
    "PROGRESS",
    "RESULT",
    "RUN_FILES",
    "RUN_JSON",
    "RUN_SCHEMA",
    "SCALARS",
    "TENSORBOARD",
    "executions",
    "finished_steps",
    "migrate_run_json",
    "read_run_json",
    "remove_run_files",
    "remove_temporary_files",
    "truncate_scalars",
]
