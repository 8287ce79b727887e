"""``rrls check``: the smoke test of the physics stack (what it runs: :mod:`rrls.check`). One
module per command, so that a command's options and what it does are read in one place."""

from __future__ import annotations

import argparse

from rrls.argtypes import positive_int, seed_value, task_key
from rrls.cli.parsing import task_keys
from rrls.deprecation import DeprecatedOption

NAME = "check"


def add_parser(sub: argparse._SubParsersAction) -> argparse.ArgumentParser:
    """Register ``rrls check`` on the ``rrls`` sub-command parser."""
    check = sub.add_parser(
        NAME,
        help="build every env and run short random episodes at the nominal point and set corners",
        description="Smoke-test the physics stack: for each task, build the robust and force "
        "envs and run one short random-action episode at the nominal model and at every corner "
        "of every uncertainty set. Prints a table; exit status 1 if any episode failed.",
    )
    check.add_argument(
        "--task",
        action="append",
        type=task_key,
        metavar="TASK",
        help="only this task (repeatable; default: every registered task: "
        f"{', '.join(task_keys())})",
    )
    check.add_argument(
        "--steps", type=positive_int, default=100, help="steps per episode (default: %(default)s)"
    )
    check.add_argument(
        "--episode-seed",
        type=seed_value,
        default=0,
        metavar="S",
        help="root of the episodes' seeds: resets and random actions (default: %(default)s)",
    )
    check.add_argument(  # --seed names a training seed in every other command
        "--seed", dest="episode_seed", type=seed_value, action=DeprecatedOption,
        new="--episode-seed",
    )  # fmt: skip
    return check


def run(args: argparse.Namespace) -> int:
    """Run the smoke test; exit status 1 if any episode failed."""
    from rrls.check import main as check_main

    return check_main(args.task, args.steps, args.episode_seed)


__all__ = ["NAME", "add_parser", "run"]
