"""The side of ``rrls submit`` that runs and writes: the evaluation under the benchmark's
protocol (the same as the benchmark's own runs) and the installation of the run directory."""

from __future__ import annotations

import json
import shutil
import time
from pathlib import Path
from typing import Any


def discard(staging: Path, made: list[Path]) -> None:
    """Remove a submission's staging directory and the directories it created."""
    shutil.rmtree(staging, ignore_errors=True)
    for path in reversed(made):
        try:
            path.rmdir()  # only if empty: another command's files stay
        except OSError:
            pass


def jsonable(meta: dict[str, Any]) -> dict[str, Any]:
    return json.loads(json.dumps(meta, default=str))


def install(root: Path, staging: Path, final: Path, result: dict[str, Any]) -> None:
    """Move the evaluated ``staging`` directory to ``final`` (replacing a previous submission
    only once the new one is complete); ``result.json`` goes in last, as for trained runs."""
    from rrls.experiments.store import write_result

    (staging / "eval" / ".lock").unlink(missing_ok=True)
    final.parent.mkdir(parents=True, exist_ok=True)
    trash = None
    if final.exists():
        trash = root / "submissions" / ".replaced" / f"{final.name}-{time.time_ns()}"
        trash.parent.mkdir(parents=True, exist_ok=True)
        final.rename(trash)
    staging.rename(final)
    write_result(final, result)
    if trash is not None:
        shutil.rmtree(trash, ignore_errors=True)
