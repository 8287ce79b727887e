"""The evaluation's saved chunks (``out_dir/chunks/000003.npz``): fixed blocks of ``CHUNK``
consecutive episode rows, independent of the number of workers and of the work split, each
written atomically when its last row finishes; a re-run loads them instead of running them,
and a damaged one is reported by name and recomputed."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np

from rrls.files import atomic_save_npz

__all__ = ["CHUNK", "chunk_path", "load_chunk", "remove_leftovers", "save_chunk", "saved"]

CHUNK = 50  # episodes per saved chunk: the unit of saving and resuming (not of work sharing)


def chunk_path(chunk_dir: Path, c: int) -> Path:
    return Path(chunk_dir) / f"{c:06d}.npz"


def save_chunk(chunk_dir: Path, c: int, cols: dict[str, np.ndarray], block: slice) -> None:
    atomic_save_npz(chunk_path(chunk_dir, c), **{k: v[block] for k, v in cols.items()})


def saved(chunk_dir: Path, n: int, chunk: int = CHUNK) -> tuple[int, int]:
    """``(chunks, episodes)`` of ``n`` episode rows already saved in ``chunk_dir``: what an
    interrupted evaluation keeps, and a re-run loads instead of running."""
    chunks = episodes = 0
    for c in range(-(-n // chunk)):
        if chunk_path(chunk_dir, c).exists():
            chunks += 1
            episodes += min(chunk, n - c * chunk)
    return chunks, episodes


def remove_leftovers(chunk_dir: Path) -> list[Path]:
    """Delete the temporary files of chunk writes killed half-way (``.000003.npz.XXXX.tmp``).

    ``evaluate`` holds the directory's lock, so no live writer owns them.
    """
    leftovers = sorted(chunk_dir.glob(".*.tmp"))
    for path in leftovers:
        path.unlink(missing_ok=True)
    return leftovers


def load_chunk(path: Path, cols: dict[str, np.ndarray], block: slice) -> bool:
    """Fill ``cols[block]`` from a saved chunk; a truncated, empty or malformed file is reported
    by name, removed and recomputed (``False``), never a bare ``BadZipFile``/``EOFError``."""
    size = block.stop - block.start
    try:
        with np.load(path, allow_pickle=False) as f:
            data = {k: np.asarray(f[k]) for k in cols}
        for k, v in data.items():
            if v.shape != (size,) or not np.can_cast(v.dtype, cols[k].dtype, "same_kind"):
                raise ValueError(f"column {k!r} has shape {v.shape} and dtype {v.dtype}")
    except Exception as err:  # noqa: BLE001 - any unreadable content: recompute the chunk
        warnings.warn(
            f"chunk file {path} is unreadable ({type(err).__name__}: {err}); recomputing it",
            stacklevel=3,
        )
        path.unlink(missing_ok=True)
        return False
    for k, v in data.items():
        cols[k][block] = v
    return True
