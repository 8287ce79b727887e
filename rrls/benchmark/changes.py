"""All or nothing: the changes one command makes to a benchmark directory (``rrls submit``,
``rrls withdraw``), applied together or not at all.

Every check runs before the first change (the caller's part); the changes themselves are
renames and sealed writes made under the benchmark's lock, each recorded with its undo. A
failure at any step (a full disk, a refused write, Ctrl-C) undoes the steps already made in
reverse order, so the directory is left byte for byte as it was: the earlier submission in
place, ``benchmark.json`` unchanged, no run half installed. What a success removes goes to a
trash folder first and is deleted only once every change is in.

>>> import tempfile, pathlib
>>> root = pathlib.Path(tempfile.mkdtemp())
>>> (root / "a").write_text("old")
3
>>> try:
...     with Changes(root) as change:
...         change.write(root / "a", b"new", sealed=False)
...         raise OSError("disk full")
... except OSError:
...     pass
>>> (root / "a").read_text()
'old'
"""

from __future__ import annotations

import os
import shutil
import time
from collections.abc import Callable
from pathlib import Path
from types import TracebackType
from typing import Any

from rrls import files
from rrls.files import atomic_write_bytes

__all__ = ["TRASH", "Changes", "rebuild_folder"]

#: where removed and replaced runs wait until the whole change is in (under the benchmark)
TRASH = Path("submissions") / ".trash"


class Changes:
    """A set of changes to ``root``, undone in reverse order if any of them fails."""

    def __init__(self, root: str | Path) -> None:
        self.root = Path(root)
        self._undo: list[Callable[[], None]] = []
        self._trash: list[Path] = []

    def __enter__(self) -> Changes:
        return self

    def __exit__(
        self,
        kind: type[BaseException] | None,
        err: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        if kind is None:
            for path in self._trash:  # the change is in: what it replaced can go
                shutil.rmtree(path, ignore_errors=True)
            self._prune(self.root / TRASH)
            return
        for undo in reversed(self._undo):
            try:
                undo()
            except OSError:
                pass

    def mkdirs(self, path: Path) -> None:
        """Create ``path`` and its missing parents (removed again if the change fails)."""
        missing = []
        for p in (Path(path), *Path(path).parents):
            if p.exists():
                break
            missing.append(p)
        for p in reversed(missing):
            p.mkdir()
            self._undo.append(lambda p=p: p.rmdir())

    def move(self, src: Path, dst: Path) -> None:
        """Rename ``src`` to ``dst`` (a new name on the same file system: atomic)."""
        src, dst = Path(src), Path(dst)
        if dst.exists():
            raise FileExistsError(f"{dst} exists: nothing was changed")
        self.mkdirs(dst.parent)
        os.rename(src, dst)
        self._undo.append(lambda: os.rename(dst, src))

    def remove(self, path: Path) -> None:
        """Take ``path`` out of the benchmark: to the trash now, deleted once all is in."""
        trash = self.root / TRASH / f"{Path(path).name}-{os.getpid()}-{time.time_ns()}"
        self.move(path, trash)
        self._trash.append(trash)

    def write(self, path: Path, data: bytes, sealed: bool = True) -> None:
        """Write ``data`` to ``path`` atomically (and seal it): the old bytes (or none) and the
        old seal come back if the change fails."""
        path = Path(path)
        paths = (path, files.seal_path(path)) if sealed else (path,)
        before = {p: p.read_bytes() if p.exists() else None for p in paths}
        self.mkdirs(path.parent)
        self._undo.append(lambda: _restore(before))
        if sealed:
            files.write_checked(path, data)
        else:
            atomic_write_bytes(path, data)

    def _prune(self, path: Path) -> None:
        """Remove the trash folders if empty (another command's entries stay)."""
        for p in (path, path.parent):
            try:
                p.rmdir()
            except OSError:
                return


def _restore(before: dict[Path, bytes | None]) -> None:
    for path, data in before.items():
        if data is None:
            path.unlink(missing_ok=True)
        else:
            atomic_write_bytes(path, data)


def rebuild_folder(root: str | Path, name: str, build: Callable[[Path], Any]) -> Path:
    """Rebuild ``root/name`` (the result store, the report) whole or not at all: ``build``
    writes a new folder beside it, which replaces the old one only once it is complete; a
    failure while building or swapping leaves the old folder as it was. Returns the folder."""
    root = Path(root)
    fresh = root / f".{name}.new-{os.getpid()}-{time.time_ns()}"
    fresh.mkdir(parents=True)
    try:
        build(fresh)
        with Changes(root) as change:
            if (root / name).exists():
                change.remove(root / name)
            change.move(fresh, root / name)
    finally:
        shutil.rmtree(fresh, ignore_errors=True)  # gone already unless something failed
    return root / name
