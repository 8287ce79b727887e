"""Atomic file writes: a reader (or a resumed run) sees the old file or the new one, never half."""

from __future__ import annotations

import errno
import hashlib
import io
import json
import os
import tempfile
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any, ClassVar

import numpy as np


def _umask() -> int:
    """The process umask (read by setting and restoring it: there is no getter)."""
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def atomic_write_bytes(path: str | Path, data: bytes) -> Path:
    """Write ``data`` to a temporary file beside ``path``, fsync, then rename it to ``path``.

    The file gets the mode ``open()`` would give it (0666 minus the umask), not ``mkstemp``'s
    0600: results on a shared cluster stay readable by the group the user intends.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        os.fchmod(fd, 0o666 & ~_umask())
        with os.fdopen(fd, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return path


def json_bytes(obj: Any) -> bytes:
    """How rrls writes JSON files (indented, keys sorted, a final newline)."""
    return (json.dumps(obj, indent=2, sort_keys=True) + "\n").encode()


def json_fingerprint(obj: Any) -> str:
    """16 hex digits of the SHA-256 of ``obj``'s canonical JSON (keys sorted, no spaces): the
    same fields give the same fingerprint on any machine and in any key order."""
    text = json.dumps(obj, sort_keys=True, separators=(",", ":"), allow_nan=False)
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def atomic_write_json(path: str | Path, obj: Any) -> Path:
    return atomic_write_bytes(path, json_bytes(obj))


def atomic_save_npz(path: str | Path, **arrays: np.ndarray) -> Path:
    buf = io.BytesIO()
    np.savez(buf, **arrays)
    return atomic_write_bytes(path, buf.getvalue())


def table_bytes(path: str | Path, frame: Any) -> bytes:
    """A pandas DataFrame as Parquet (``.parquet``, needs pyarrow) or CSV (any other suffix)."""
    buf = io.BytesIO()
    if Path(path).suffix == ".parquet":
        frame.to_parquet(buf, index=False)
    else:
        frame.to_csv(buf, index=False, float_format="%.17g")
    return buf.getvalue()


def atomic_write_table(path: str | Path, frame: Any) -> Path:
    """A pandas DataFrame as Parquet (``.parquet``, needs pyarrow) or CSV (any other suffix)."""
    return atomic_write_bytes(path, table_bytes(path, frame))


@contextmanager
def waiting_lock(path: str | Path) -> Iterator[None]:
    """Hold an exclusive ``flock`` on ``path`` (created if missing), waiting for the holder:
    read-modify-write of a shared file (``benchmark.json``) by concurrent commands loses no
    update. A killed holder releases it (the lock belongs to the open file)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o666)
    try:
        try:
            import fcntl
        except ImportError:  # pragma: no cover - not POSIX: no locking
            yield
            return
        fcntl.flock(fd, fcntl.LOCK_EX)
        yield
    finally:
        os.close(fd)  # closing the descriptor releases the flock


class DirectoryLock:
    """An exclusive lock on a directory (``DIR/.lock``) for one run at a time.

    Two evaluations writing into the same directory would mix their chunks and summaries; the
    second one is refused with a ``FileExistsError`` naming the directory. The lock is an
    ``flock`` held by the open file, so a killed process releases it (no stale lock files).
    """

    #: (directory, thread) pairs held, and how many holders: a thread may nest its own locks (a
    #: benchmark's run holds its directory, then trains there); another thread or process may not
    _held: ClassVar[dict[tuple[Path, int], int]] = {}

    def __init__(self, directory: str | Path) -> None:
        self.directory = Path(directory)
        self._fd: int | None = None
        self._nested = False

    def __enter__(self) -> DirectoryLock:
        self.directory.mkdir(parents=True, exist_ok=True)
        key = (self.directory.resolve(), threading.get_ident())
        if key in self._held:
            self._held[key] += 1
            self._nested = True
            return self
        fd = os.open(self.directory / ".lock", os.O_RDWR | os.O_CREAT, 0o666)
        try:
            import fcntl
        except ImportError:  # pragma: no cover - not POSIX: no locking
            self._fd = fd
            return self
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            os.close(fd)
            raise FileExistsError(
                f"{self.directory} is in use by another running rrls command; wait for it to "
                "finish or use another output directory"
            ) from None
        self._fd = fd
        self._held[key] = 1
        return self

    def __exit__(self, *exc: object) -> None:
        key = (self.directory.resolve(), threading.get_ident())
        if key in self._held:
            self._held[key] -= 1
            if self._held[key] == 0:
                del self._held[key]
        if self._nested:
            self._nested = False
            return
        if self._fd is not None:
            os.close(self._fd)  # closing the descriptor releases the flock
            self._fd = None


def resource_error(err: BaseException) -> str:
    """A filesystem or memory error in words: what failed, on which file, and what to do."""
    if isinstance(err, MemoryError):
        said = str(err).strip()  # a check made before allocating says what and how much
        if said and "\n" not in said and len(said) < 300:
            return f"out of memory: {said}"
        return "out of memory: choose smaller sizes (--mesh, --episodes, --workers, --seeds)"
    name = getattr(err, "filename", None)
    what = getattr(err, "strerror", None) or str(err) or type(err).__name__
    hint = {
        errno.EROFS: "the file system is read-only: choose another --out",
        errno.ENOSPC: "the disk is full: free space or choose another --out",
        errno.EDQUOT: "the disk quota is exceeded: free space or choose another --out",
        errno.EACCES: "permission denied: choose another --out",
        errno.EPERM: "permission denied: choose another --out",
        errno.EISDIR: "a directory stands where a file is expected",
        errno.ENOTDIR: "a file stands where a directory is expected",
        errno.ELOOP: "a loop of symbolic links: choose another path",
    }.get(getattr(err, "errno", None), "")
    where = f" ({name})" if name else ""
    return f"{what}{where}" + (f"; {hint}" if hint else "")
