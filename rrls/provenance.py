"""Where a number came from: the source commit and the machine, recorded with every run and
every exported reference (a result shipped without them cannot be re-checked)."""

from __future__ import annotations

import os
import platform
import subprocess
from pathlib import Path
from typing import Any

__all__ = ["machine", "source_commit", "versions"]


def source_commit() -> str | None:
    """The git commit of the rrls source in use (``+dirty`` when tracked files differ from
    it), or ``None`` for an installed wheel."""
    root = Path(__file__).resolve().parents[1]
    if not (root / ".git").exists():
        return None
    try:
        head = subprocess.run(
            ["git", "-C", str(root), "rev-parse", "HEAD"],
            capture_output=True,
            text=True,
            timeout=5,
            check=True,
        ).stdout.strip()
        dirty = subprocess.run(
            ["git", "-C", str(root), "diff", "--quiet", "HEAD", "--", "rrls"],
            capture_output=True,
            timeout=5,
        ).returncode
    except (OSError, subprocess.SubprocessError):
        return None
    return head + ("+dirty" if dirty else "")


def machine() -> dict[str, Any]:
    """The CPU (model, cores, numpy's SIMD level: what decides the last bits of training)."""
    model = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                model = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    simd = ""
    try:
        from numpy._core._multiarray_umath import __cpu_features__ as features

        simd = next((f for f in ("X86_V4", "X86_V3", "X86_V2") if features.get(f)), "")
    except (ImportError, AttributeError):  # numpy's detection table moved: leave it out
        pass
    return {
        "cpu": model,
        "cores": os.cpu_count(),
        "simd": simd,
        "system": f"{platform.system()} {platform.machine()}",
    }


def versions() -> dict[str, str]:
    """The versions an evaluation depends on (training adds torch's)."""
    import gymnasium
    import mujoco
    import numpy as np

    from rrls import __version__

    return {
        "rrls": __version__,
        "gymnasium": gymnasium.__version__,
        "mujoco": mujoco.__version__,
        "numpy": np.__version__,
        "python": platform.python_version(),
    }
