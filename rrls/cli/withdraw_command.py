"""``rrls withdraw``: take an algorithm's submissions out of a benchmark, undoing ``rrls submit``
(the library's :func:`rrls.submissions.withdraw.remove_submission`). Named
``withdraw_command`` because :mod:`rrls.submissions.withdraw` does the work."""

from __future__ import annotations

import argparse
import shlex

from rrls.argtypes import seed_value
from rrls.cli.parsing import fail

NAME = "withdraw"


def add_parser(sub: argparse._SubParsersAction) -> argparse.ArgumentParser:
    """Register ``rrls withdraw`` on the ``rrls`` sub-command parser."""
    w = sub.add_parser(
        NAME,
        help="take an algorithm's submissions out of a benchmark (undoes `rrls submit`)",
        description="Remove the submitted runs of --algo (all, or those of --task / --seed) "
        "from BENCH_DIR; a task left without runs leaves a submissions-only benchmark's task "
        "list, so later reports stay complete. The benchmark's own runs are never removed.",
    )
    w.add_argument("bench_dir", metavar="BENCH_DIR", help="a benchmark directory")
    w.add_argument("--algo", required=True, metavar="NAME", help="the submitted algorithm")
    w.add_argument("--task", metavar="TASK", help="only its runs on this task")
    w.add_argument(
        "--seed", type=seed_value, metavar="S", help="only its runs of this training seed"
    )
    return w


def run(args: argparse.Namespace) -> int:
    """Remove the submitted runs and say how to rebuild the report."""
    from rrls.submissions.steps import SubmitError
    from rrls.submissions.withdraw import remove_submission

    try:
        names = remove_submission(args.bench_dir, args.algo, args.task, args.seed)
    except SubmitError as err:
        return fail("withdraw", str(err))
    print("withdrawn: " + ", ".join(names))
    print(f"report: rrls report {shlex.quote(str(args.bench_dir))}")
    return 0


__all__ = ["NAME", "add_parser", "run"]
