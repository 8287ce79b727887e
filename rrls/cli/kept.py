"""What a command kept when Ctrl-C came, for the commands that do not say it themselves (the
others raise an :class:`~rrls.interrupts.Interruption` that does): read from the disk then.

``submit`` and ``withdraw`` change a benchmark all or nothing (:mod:`rrls.benchmark.changes`),
so the disk says whether the change is in; ``check`` writes nothing.
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path

from rrls.interrupts import NOTHING_YET

__all__ = ["kept_after"]


def kept_after(args: argparse.Namespace, started: float) -> tuple[str, bool | None]:
    """``(what was kept, whether the same command goes on)`` for ``args.command`` stopped by
    Ctrl-C; ``started``: when it began (``time.time()``)."""
    if args.command == "submit":
        return _submitted(args, started)
    if args.command == "withdraw":
        return _withdrawn(args)
    if args.command == "check":
        return "nothing written (rrls check writes no file)", False
    return NOTHING_YET, False


def _task_key(task: str | None) -> str | None:
    from rrls.tasks import get_task

    try:
        return None if task is None else get_task(task).key
    except ValueError:  # refused by the command already, or about to be
        return task


def _submitted(args: argparse.Namespace, started: float) -> tuple[str, bool | None]:
    """The submission stored (its run directory written since ``started``), else what its
    evaluation left in the staging folder of this process."""
    root = Path(args.bench_dir)
    name = f"{args.algo}-{_task_key(args.task)}-*-seed{args.seed}"
    for result in sorted((root / "runs").glob(f"{name}/result.json")):
        if result.stat().st_mtime >= started:
            return f"the submission is stored in {result.parent}", None
    staged = sorted((root / "submissions" / ".staging").glob(f"*-{os.getpid()}-*"))
    if staged:
        return (
            f"nothing was submitted; its partial evaluation is left in {staged[0]}, which no "
            "re-run uses: delete it",
            False,
        )
    return "nothing was submitted (nothing kept: a re-run evaluates from the start)", False


def _withdrawn(args: argparse.Namespace) -> tuple[str, bool | None]:
    """Whether the runs to withdraw are still there: all of them, or none."""
    from rrls.files import read_checked_json
    from rrls.rundir import RESULT

    root = Path(args.bench_dir)
    task = _task_key(args.task)
    left = 0
    for path in sorted((root / "runs").glob(f"*/{RESULT}")):
        try:
            result = read_checked_json(path)
        except (OSError, ValueError):
            continue
        if (
            "submitted" in result
            and str(result.get("algorithm", "")).lower() == str(args.algo).lower()
            and task in (None, result.get("task"))
            and args.seed in (None, result.get("seed"))
        ):
            left += 1
    if left:
        return (
            f"nothing withdrawn (all or nothing): {left} submitted run(s) of {args.algo} still in "
            f"{root / 'runs'}",
            True,
        )
    done = f"the withdrawal is complete: no submitted run of {args.algo} left in {root / 'runs'}"
    return done, None
