"""The ``rrls`` program: the top-level parser, ``main`` and the dispatch to the command modules
(one per command: ``add_parser(sub)`` registers its options, ``run(args)`` does it). Thin: the
commands parse arguments and call the library. Every command module is imported when the
parser is built, after ``main`` has loaded the task plug-ins (the help texts list every task);
none of them imports torch before it runs, so ``rrls --help`` and the torch-free commands work
without the ``train`` extra."""

from __future__ import annotations

import argparse
import sys
import time
from types import ModuleType

from rrls.cli.parsing import USAGE_ERRORS, Parser, refuse_link_loops, unknown_option
from rrls.extras import install_hint


def commands() -> tuple[ModuleType, ...]:
    """The command modules, in ``rrls --help``'s order."""
    from rrls.cli import (
        benchmark_command,
        check_command,
        dynamic_command,
        evaluate_command,
        plot_command,
        quickstart_command,
        report_command,
        submit_command,
        train_command,
        withdraw_command,
    )

    return (
        check_command,
        evaluate_command,
        train_command,
        dynamic_command,
        quickstart_command,
        benchmark_command,
        report_command,
        submit_command,
        withdraw_command,
        plot_command,
    )


def build_parser(with_train: bool = True) -> argparse.ArgumentParser:
    """The `rrls` parser; `rrls train`'s options only `with_train` (they need torch)."""
    from rrls import __version__
    from rrls.seeds import EXAMPLES

    parser = Parser(
        prog="rrls",
        description="Robust Reinforcement Learning Suite. One meaning per flag in every "
        "command: --seed S is one training seed and --seeds a list or range of them "
        f"({EXAMPLES}); --episode-seed S the root of the episodes' seeds of an evaluation; "
        "--workers N that many worker processes, 0 none (the work runs in this process), by "
        "default the machine's cores (train: what pays off; benchmark refuses 0: each run needs a "
        "process of its own); --mesh N points per dimension; "
        "--physics v5|paper.",
    )
    parser.add_argument("--version", action="version", version=f"rrls {__version__}")
    sub = parser.add_subparsers(dest="command", required=True)
    for command in commands():
        command.add_parser(sub)
    if with_train:  # the options come from the dataclasses, which need torch: only for `train`
        from rrls.cli.train_options import add_train_arguments

        add_train_arguments(sub.choices["train"])
    parser.subcommands = dict(sub.choices)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Run one command. Bad input (``USAGE_ERRORS``) is one line on stderr and exit status 2."""
    argv = sys.argv[1:] if argv is None else list(argv)
    import os

    from rrls.envs.base import QUIET_XML_DEPRECATIONS
    from rrls.registry import load_task_plugins

    # Gymnasium's own XML files use attributes MuJoCo deprecates (HalfCheetah's settotalmass):
    # nothing a user of rrls's commands can act on; their own code still sees the warning
    os.environ.setdefault(QUIET_XML_DEPRECATIONS, "1")
    load_task_plugins()  # tasks of installed packages (entry point group ``rrls.tasks``)
    with_train = argv[:1] == ["train"]
    if with_train:  # `train`'s options are generated from the dataclasses, which need torch
        try:
            import torch  # noqa: F401
        except ImportError as err:
            print(f"rrls train needs torch: {install_hint('train')} ({err})", file=sys.stderr)
            return 2
    parser = build_parser(with_train)
    try:
        args, extras = parser.parse_known_args(argv)
    except SystemExit as stop:  # a bad option (one line already printed), --help, --version
        return stop.code if isinstance(stop.code, int) else 2
    if extras:
        sub = parser.subcommands.get(args.command, parser)
        print(unknown_option(sub, args.command, extras), file=sys.stderr)
        return 2
    started = time.time()  # what an interrupted command wrote since: rrls.cli.kept
    from rrls.interrupts import sigterm_as_ctrl_c

    try:
        refuse_link_loops(args)
        with sigterm_as_ctrl_c():  # a scheduler's stop keeps what Ctrl-C keeps
            return _dispatch(args)
    except USAGE_ERRORS as err:
        print(f"rrls {args.command}: error: {err}", file=sys.stderr)
        return 2
    except (OSError, MemoryError) as err:  # the machine's, not the input's: still one line
        from rrls.files import resource_error

        print(f"rrls {args.command}: error: {resource_error(err)}", file=sys.stderr)
        return 2
    except KeyboardInterrupt as stop:  # one line: what was kept, the command that goes on
        from rrls.cli.kept import kept_after
        from rrls.interrupts import Interruption, interrupted

        if isinstance(stop, Interruption):
            kept, resumes = stop.kept, stop.resumes
        else:
            kept, resumes = kept_after(args, started)
        print(interrupted(args.command, argv, kept, resumes), file=sys.stderr)
        return 130


def _dispatch(args: argparse.Namespace) -> int:
    """Run the command ``args.command`` names (argparse rejects any other)."""
    run = {command.NAME: command.run for command in commands()}
    return run[args.command](args)


__all__ = ["build_parser", "commands", "main"]
