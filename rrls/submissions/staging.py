"""Small helpers of ``rrls submit``: removing its staging folders, and metadata as JSON.
(Installing the run directory is :mod:`rrls.benchmark.changes`' all-or-nothing change.)"""

from __future__ import annotations

import json
import shutil
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
