"""The ``rrls`` command line. Thin: it parses arguments and calls the library."""

from __future__ import annotations

import argparse
import sys


def build_parser() -> argparse.ArgumentParser:
    from rrls import __version__

    parser = argparse.ArgumentParser(prog="rrls", description="Robust Reinforcement Learning Suite")
    parser.add_argument("--version", action="version", version=f"rrls {__version__}")
    sub = parser.add_subparsers(dest="command", required=True)

    check = sub.add_parser(
        "check",
        help="build every env and run short random episodes at the nominal point and set corners",
    )
    check.add_argument("--task", action="append", help="only these tasks (repeatable)")
    check.add_argument("--steps", type=int, default=100, help="steps per episode (default 100)")
    check.add_argument("--seed", type=int, default=0)
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    if args.command == "check":
        from rrls.check import main as check_main

        return check_main(args.task, args.steps, args.seed)
    raise AssertionError(args.command)  # argparse rejects unknown commands


if __name__ == "__main__":
    sys.exit(main())
