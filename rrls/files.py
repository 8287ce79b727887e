"""How every file rrls keeps is written and read back; what is *in* each file is said by the
module of its format (``rundir``: a run directory; ``benchmark.benchfile``: ``benchmark.json``;
``evaluation.evaldir``: an evaluation's folder).

- **Atomic writes**: a temporary file beside the target, fsynced, then renamed over it, so a
  reader (or a resumed run) sees the old file or the new one, never half.
- **Seals**: results files carry their SHA-256 in ``NAME.sha256`` beside them (``sha256sum``'s
  format: ``sha256sum -c NAME.sha256`` checks one by hand), the checkpoint at its end. Readers
  check it: a damaged file is a one-line ``DamagedFile`` naming it, never numbers. A file
  without a seal (written by an older rrls, or by a write killed between the file and its seal)
  is read as it is.
- **Limits**: a JSON file is read no further than ``MAX_JSON_BYTES`` and parsed no deeper than
  ``MAX_JSON_DEPTH``, so a huge, endless or hostile file is a one-line error, not a traceback.
- **Locks**: read-modify-write of a shared file waits its turn (``waiting_lock``); a directory
  is used by one command at a time (``DirectoryLock``).
"""

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

from rrls.schema import JsonError

__all__ = [
    "DAMAGE_ADVICE",
    "MAX_JSON_BYTES",
    "MAX_JSON_DEPTH",
    "SEAL_SUFFIX",
    "DamagedFile",
    "DirectoryLock",
    "atomic_save_npz",
    "atomic_write_bytes",
    "atomic_write_json",
    "atomic_write_table",
    "json_bytes",
    "json_fingerprint",
    "loads_json",
    "read_checked",
    "read_checked_json",
    "read_checked_table",
    "read_json",
    "read_limited",
    "read_sealed",
    "resource_error",
    "seal",
    "seal_path",
    "sealed_prefix",
    "table_bytes",
    "waiting_lock",
    "write_checked",
    "write_checked_json",
    "write_checked_table",
    "write_sealed",
]


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


# sealed files

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
        raise DamagedFile(f"{side} is damaged (not a SHA-256 line); {DAMAGE_ADVICE}")
    return digest


#: what a ``DamagedFile`` message advises
DAMAGE_ADVICE = "the results in it cannot be trusted: restore it from a copy or re-run that step"


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
            raise DamagedFile(f"{path} is damaged ({err.reason}); {DAMAGE_ADVICE}") from None
    digest = _expected(path)
    if digest is not None and hashlib.sha256(data).hexdigest() != digest:
        raise DamagedFile(
            f"{path} is damaged (its SHA-256 does not match {seal_path(path).name}); "
            + DAMAGE_ADVICE
        )
    return data


def read_checked_json(path: Path) -> dict[str, Any]:
    """A sealed (or older unsealed) JSON object file; damage (not JSON, larger than
    ``MAX_JSON_BYTES``, nested deeper than ``MAX_JSON_DEPTH``) is a one-line ``DamagedFile``."""
    data = read_checked(path, MAX_JSON_BYTES)
    try:
        obj = loads_json(data, str(path))
    except JsonError as err:
        raise DamagedFile(f"{path} is damaged ({err.reason}); {DAMAGE_ADVICE}") from None
    if not isinstance(obj, dict):
        raise DamagedFile(
            f"{path} is damaged (it holds a JSON {type(obj).__name__}, not an object); "
            + DAMAGE_ADVICE
        )
    return obj


def read_checked_table(path: Path) -> Any:
    """A sealed (or older unsealed) Parquet / CSV table as a DataFrame; damage is one line."""
    import pandas as pd

    data = read_checked(path)
    try:
        if Path(path).suffix == ".parquet":
            return pd.read_parquet(io.BytesIO(data))
        return pd.read_csv(io.BytesIO(data))
    except Exception as err:  # noqa: BLE001 - any unreadable table: name the file
        first = (str(err).strip().splitlines() or [type(err).__name__])[0]
        raise DamagedFile(f"{path} is damaged (unreadable: {first}); {DAMAGE_ADVICE}") from None


def write_checked_json(path: Path, obj: Any) -> Path:
    """``obj`` as rrls writes JSON (``json_bytes``), sealed."""
    return write_checked(path, json_bytes(obj))


def write_checked_table(path: Path, frame: Any) -> Path:
    """A DataFrame as ``table_bytes`` writes it, sealed."""
    return write_checked(path, table_bytes(path, frame))


def sealed_prefix(path: Path, data: bytes) -> bytes:
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
                f"{seal_path(path).name}); {DAMAGE_ADVICE}"
            )
        running.update(data[start : end + 1])
        start = end + 1


# JSON read with limits

#: the most bytes a JSON file rrls reads may hold: its own files hold at most ~15 kB, and a
#: larger one is read into memory whole before any field can be checked
MAX_JSON_BYTES = 16 * 2**20
#: the deepest nesting a JSON value rrls reads may have: its own files nest at most 7 levels,
#: and Python's parser recurses (100 000 ``[`` would be a ``RecursionError`` traceback)
MAX_JSON_DEPTH = 64


def read_limited(path: str | Path, limit: int = MAX_JSON_BYTES) -> bytes:
    """``path``'s bytes, or a ``JsonError`` naming it when it holds more than ``limit`` (read
    no further than that: a huge or endless file costs no memory)."""
    with open(path, "rb") as f:
        data = f.read(limit + 1)
    if len(data) > limit:
        raise JsonError(str(path), f"it holds more than {limit:,} bytes; valid: at most {limit:,}")
    return data


def loads_json(data: bytes | bytearray | str, where: str) -> Any:
    """``data`` parsed as JSON, or a one-line ``JsonError`` naming ``where`` (the file): not
    UTF-8, not JSON, more than ``MAX_JSON_BYTES`` or nested deeper than ``MAX_JSON_DEPTH``.
    Every JSON reader of rrls goes through here, so none can fail with a traceback."""
    if not isinstance(data, (str, bytes, bytearray)):
        shown = repr(data) if len(repr(data)) <= 60 else repr(data)[:57] + "..."
        raise JsonError(where, f"it holds {shown}; valid: JSON text")
    if len(data) > MAX_JSON_BYTES:
        raise JsonError(
            where, f"it holds {len(data):,} bytes; valid: at most {MAX_JSON_BYTES:,} bytes of JSON"
        )
    deep = f"it is nested more than {MAX_JSON_DEPTH} levels deep; valid: JSON nested at most "
    deep += f"{MAX_JSON_DEPTH} levels"
    try:
        text = data if isinstance(data, str) else bytes(data).decode("utf-8")
        value = json.loads(text)
    except UnicodeDecodeError as err:
        raise JsonError(where, f"not UTF-8 text ({err})") from None
    except RecursionError:  # the parser recursed past Python's limit: deeper than ours
        raise JsonError(where, deep) from None
    except ValueError as err:
        raise JsonError(where, f"not valid JSON: {err}", syntax=True) from None
    if _depth(value) > MAX_JSON_DEPTH:
        raise JsonError(where, deep)
    return value


def read_json(path: str | Path) -> Any:
    """The JSON value in ``path`` (through ``read_limited`` and ``loads_json``)."""
    return loads_json(read_limited(path), str(path))


def _depth(value: Any) -> int:
    """How deep ``value``'s lists and objects nest (a scalar: 0), without recursion."""
    deepest, stack = 0, [(value, 1)]
    while stack:
        item, level = stack.pop()
        if isinstance(item, (list, dict)):
            deepest = max(deepest, level)
            if level <= MAX_JSON_DEPTH:  # deeper is refused anyway: no need to look further
                items = item.values() if isinstance(item, dict) else item
                stack.extend((x, level + 1) for x in items)
    return deepest
