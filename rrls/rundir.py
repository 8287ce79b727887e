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
"""

from __future__ import annotations

import hashlib
import json
import shutil
from pathlib import Path

from rrls._io import atomic_write_bytes

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


def finished_steps(run_dir: Path) -> int | None:
    """The steps of the finished run in ``run_dir`` (policy and run.json written), else None."""
    try:
        if (run_dir / POLICY).exists():
            return int(json.loads((run_dir / RUN_JSON).read_text())["steps"])
    except (OSError, ValueError, KeyError):
        pass
    return None


def remove_run_files(run_dir: Path) -> None:
    """What a previous run left (its checkpoint, policies, logs)."""
    for name in RUN_FILES:
        (run_dir / name).unlink(missing_ok=True)
    shutil.rmtree(run_dir / TENSORBOARD, ignore_errors=True)


def remove_temporary_files(run_dir: Path) -> None:
    """Temporary files of atomic writes killed half-way (``.checkpoint.pt.XXXX.tmp``)."""
    for path in run_dir.glob(".*.tmp"):
        path.unlink(missing_ok=True)


def truncate_scalars(path: Path, step: int) -> None:
    """Drop curve rows written after the checkpoint being resumed (they will be redone)."""
    if not path.exists():
        return
    lines = path.read_text(encoding="utf-8").splitlines(keepends=True)
    rows = [ln for ln in lines[1:] if ln.endswith("\n") and int(ln.split(",", 1)[0]) <= step]
    atomic_write_bytes(path, "".join(lines[:1] + rows).encode())
