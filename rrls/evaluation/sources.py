"""Where a policy comes from and what it declares, for the record a submission keeps: its kind,
source and file hash (``policy_source``), its declared shapes (``policy_shapes``)."""

from __future__ import annotations

import hashlib
from pathlib import Path
from typing import Any

from rrls.evaluation.policies import MLPPolicy, is_attribute_reference, is_sb3

__all__ = ["file_sha256", "policy_shapes", "policy_source"]


def policy_shapes(policy: Any) -> tuple[tuple[int, ...], tuple[int, ...]] | None:
    """The observation and action shapes a policy declares (rrls MLP, SB3), else ``None``."""
    if isinstance(policy, MLPPolicy):
        return (policy.obs_dim,), (policy.act_dim,)
    obs, act = getattr(policy, "obs_shape", None), getattr(policy, "act_shape", None)
    if obs is not None and act is not None:
        return tuple(obs), tuple(act)
    return None


def file_sha256(path: str | Path) -> str:
    """The SHA-256 of a file's bytes (provenance of a submitted policy)."""
    digest = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def policy_source(obj: Any) -> dict[str, Any]:
    """Where a policy comes from: ``kind`` (``rrls-npz``, ``rrls-run``, ``sb3-zip``,
    ``module-attribute``, ``torch-module``, ``sb3-model``, ``callable``), ``source`` (the path,
    reference or type) and ``sha256`` of the file holding it (a module's source file for
    ``module:attribute``; ``None`` for objects in memory)."""
    if isinstance(obj, (str, Path)):
        text = str(obj)
        if isinstance(obj, str) and is_attribute_reference(text) and not Path(text).exists():
            import importlib.util

            origin = None
            try:
                found = importlib.util.find_spec(text.partition(":")[0])
                origin = found.origin if found else None
            except (ImportError, ValueError):
                origin = None
            sha = file_sha256(origin) if origin and Path(origin).is_file() else None
            return {"kind": "module-attribute", "source": text, "sha256": sha, "file": origin}
        path = Path(obj)
        if path.is_dir():
            file = next(
                (path / n for n in ("policy.npz", "final/policy.npz") if (path / n).is_file()), None
            )
            sha = file_sha256(file) if file else None
            return {
                "kind": "rrls-run",
                "source": str(path.resolve()),
                "sha256": sha,
                "file": str(file),
            }
        kind = "sb3-zip" if path.suffix == ".zip" else "rrls-npz"
        sha = file_sha256(path) if path.is_file() else None
        return {
            "kind": kind,
            "source": str(path.resolve()),
            "sha256": sha,
            "file": str(path.resolve()),
        }
    module_names = {c.__module__.split(".")[0] for c in type(obj).__mro__}
    if is_sb3(obj):
        kind = "sb3-model"
    elif "torch" in module_names and hasattr(obj, "parameters"):
        kind = "torch-module"
    else:
        kind = "callable"
    name = getattr(obj, "__qualname__", None) or type(obj).__qualname__
    module = getattr(obj, "__module__", None) or type(obj).__module__
    return {"kind": kind, "source": f"{module}.{name}", "sha256": None, "file": None}
