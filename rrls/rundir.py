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

Results files (``result.json``, ``scalars.csv``, ``dynamic.csv``, the evaluation's
``episodes.parquet``/``.csv`` and ``summary.json``, the benchmark's ``benchmark.json``) are
sealed too, without changing their format: beside each, ``NAME.sha256`` holds its SHA-256 in
``sha256sum``'s format (``sha256sum -c NAME.sha256`` checks it by hand). Readers check it
(``read_checked``): a damaged file is a one-line ``DamagedFile`` error naming it, never numbers.
A file without a seal (written by an older rrls, or by a write killed between the file and its
seal) is read as it is.
"""

from __future__ import annotations

import hashlib
import shutil
from pathlib import Path
from typing import Any

from rrls._io import atomic_write_bytes
from rrls.physics import ALIASES
from rrls.schema import (
    MAX_JSON_BYTES,
    JsonError,
    Schema,
    SchemaError,
    array,
    integer,
    loads_json,
    obj,
    read_limited,
    string,
)
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

_SEAL = b"\nrrls-sha256:"
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


def write_sealed(path: Path, data: bytes) -> None:
    """Write ``data`` atomically followed by its SHA-256: ``read_sealed`` detects damage."""
    atomic_write_bytes(path, data + _SEAL + hashlib.sha256(data).hexdigest().encode())


def read_sealed(path: Path) -> bytes:
    """The bytes ``write_sealed`` wrote; a one-line ``ValueError`` naming the file if damaged."""
    raw = Path(path).read_bytes()
    data, sep, digest = raw.rpartition(_SEAL)
    if not sep:
        raise ValueError(
            f"{path} has no checksum: damaged, truncated or written by another version of rrls; "
            "delete it (or pass --overwrite) to start again"
        )
    if hashlib.sha256(data).hexdigest().encode() != digest:
        raise ValueError(
            f"{path} is damaged (its SHA-256 does not match its content); delete it "
            "(or pass --overwrite) to start again"
        )
    return data


SEAL_SUFFIX = ".sha256"


class DamagedFile(ValueError):
    """A results file whose bytes are not those rrls wrote (one line, naming the file)."""


def seal_path(path: Path) -> Path:
    """Where ``path``'s seal lives (``NAME.sha256`` beside it)."""
    path = Path(path)
    return path.with_name(path.name + SEAL_SUFFIX)


def _seal_line(path: Path, data: bytes) -> bytes:
    return f"{hashlib.sha256(data).hexdigest()}  {Path(path).name}\n".encode()


def write_checked(path: Path, data: bytes) -> Path:
    """Write ``data`` atomically, then its seal. The old seal goes first, so a write killed
    half-way leaves an unsealed file (read as is), never a false alarm."""
    path = Path(path)
    seal_path(path).unlink(missing_ok=True)
    atomic_write_bytes(path, data)
    atomic_write_bytes(seal_path(path), _seal_line(path, data))
    return path


def seal(path: Path) -> None:
    """Seal a file written in place (``scalars.csv``, appended to while training)."""
    atomic_write_bytes(seal_path(path), _seal_line(path, Path(path).read_bytes()))


def _expected(path: Path) -> str | None:
    """The digest ``path``'s seal records (None: no seal); a damaged seal is damage."""
    side = seal_path(path)
    try:
        text = side.read_bytes().decode("ascii")
    except FileNotFoundError:
        return None
    except UnicodeDecodeError:
        text = ""
    digest = text.split(" ", 1)[0].strip()
    if len(digest) != 64 or any(c not in "0123456789abcdef" for c in digest):
        raise DamagedFile(f"{side} is damaged (not a SHA-256 line); {_ADVICE}")
    return digest


_ADVICE = "the results in it cannot be trusted: restore it from a copy or re-run that step"


def read_checked(path: Path, limit: int | None = None) -> bytes:
    """``path``'s bytes, checked against its seal (``DamagedFile`` if they differ); with
    ``limit``, a file holding more bytes is damaged too (never read whole)."""
    path = Path(path)
    if limit is None:
        data = path.read_bytes()
    else:
        try:
            data = read_limited(path, limit)
        except JsonError as err:
            raise DamagedFile(f"{path} is damaged ({err.reason}); {_ADVICE}") from None
    digest = _expected(path)
    if digest is not None and hashlib.sha256(data).hexdigest() != digest:
        raise DamagedFile(
            f"{path} is damaged (its SHA-256 does not match {seal_path(path).name}); {_ADVICE}"
        )
    return data


def read_checked_json(path: Path) -> dict[str, Any]:
    """A sealed (or older unsealed) JSON object file; damage (not JSON, larger than
    ``MAX_JSON_BYTES``, nested deeper than ``MAX_JSON_DEPTH``) is a one-line ``DamagedFile``."""
    data = read_checked(path, MAX_JSON_BYTES)
    try:
        obj = loads_json(data, str(path))
    except JsonError as err:
        raise DamagedFile(f"{path} is damaged ({err.reason}); {_ADVICE}") from None
    if not isinstance(obj, dict):
        raise DamagedFile(
            f"{path} is damaged (it holds a JSON {type(obj).__name__}, not an object); {_ADVICE}"
        )
    return obj


def read_checked_table(path: Path) -> Any:
    """A sealed (or older unsealed) Parquet / CSV table as a DataFrame; damage is one line."""
    import io

    import pandas as pd

    data = read_checked(path)
    try:
        if Path(path).suffix == ".parquet":
            return pd.read_parquet(io.BytesIO(data))
        return pd.read_csv(io.BytesIO(data))
    except Exception as err:  # noqa: BLE001 - any unreadable table: name the file
        first = (str(err).strip().splitlines() or [type(err).__name__])[0]
        raise DamagedFile(f"{path} is damaged (unreadable: {first}); {_ADVICE}") from None


def write_checked_json(path: Path, obj: Any) -> Path:
    from rrls._io import json_bytes

    return write_checked(path, json_bytes(obj))


def write_checked_table(path: Path, frame: Any) -> Path:
    from rrls._io import table_bytes

    return write_checked(path, table_bytes(path, frame))


def read_run_json(run_dir: Path) -> dict[str, Any]:
    """A finished training run's ``run.json``, checked against its schema, in today's form
    (``migrate_run_json``): a damaged or foreign file is a one-line ``DamagedFile`` naming it
    (``FileNotFoundError`` if absent)."""
    path = Path(run_dir) / RUN_JSON
    try:
        return migrate_run_json(RUN_SCHEMA.check(read_checked_json(path), str(path)))
    except SchemaError as err:
        raise DamagedFile(f"{err} ({_ADVICE})") from None


def migrate_run_json(data: dict[str, Any]) -> dict[str, Any]:
    """``run.json`` in today's form: the run's settings once, under ``config``, its ``hyper``
    every resolved hyper-parameter. A file written before (``config.hyper`` held only the
    overrides, ``hyperparameters`` beside it the resolved ones) reads as the same run."""
    if "hyperparameters" not in data:
        return data
    out = {k: v for k, v in data.items() if k != "hyperparameters"}
    out["config"] = {**(data.get("config") or {}), "hyper": data["hyperparameters"]}
    return out


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


def _sealed_prefix(path: Path, data: bytes) -> bytes:
    """The part of an append-only file its seal covers: rows appended after the last seal
    (a checkpoint) are rows the resumed run redoes. ``DamagedFile`` where no prefix ending at
    a line matches the seal."""
    digest = _expected(path)
    if digest is None:
        return data  # an older run: no seal
    running = hashlib.sha256()
    start = 0
    while True:
        if running.hexdigest() == digest:
            return data[:start]
        end = data.find(b"\n", start)
        if end < 0:
            raise DamagedFile(
                f"{path} is damaged (its SHA-256 matches no part of it recorded in "
                f"{seal_path(path).name}); {_ADVICE}"
            )
        running.update(data[start : end + 1])
        start = end + 1


def truncate_scalars(path: Path, step: int) -> None:
    """Drop curve rows written after the checkpoint being resumed (they will be redone);
    damaged rows are a one-line ``DamagedFile`` naming the file."""
    if not path.exists():
        return
    data = _sealed_prefix(path, path.read_bytes())
    try:
        lines = data.decode("utf-8").splitlines(keepends=True)
        rows = [ln for ln in lines[1:] if ln.endswith("\n") and int(ln.split(",", 1)[0]) <= step]
    except ValueError as err:  # not UTF-8, or a step that is no integer
        raise DamagedFile(f"{path} is damaged ({err}); {_ADVICE}") from None
    write_checked(path, "".join(lines[:1] + rows).encode())


__all__ = [
    "ADVERSARY",
    "CHECKPOINT",
    "DamagedFile",
    "ERROR",
    "finished_steps",
    "migrate_run_json",
    "POLICY",
    "PROGRESS",
    "read_checked",
    "read_checked_json",
    "read_checked_table",
    "read_run_json",
    "RUN_SCHEMA",
    "read_sealed",
    "remove_run_files",
    "remove_temporary_files",
    "RESULT",
    "RUN_FILES",
    "RUN_JSON",
    "SCALARS",
    "seal",
    "seal_path",
    "SEAL_SUFFIX",
    "TENSORBOARD",
    "truncate_scalars",
    "write_checked",
    "write_checked_json",
    "write_checked_table",
    "write_sealed",
]
