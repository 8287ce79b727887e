"""What every ``rrls`` command shares: the parser without abbreviations, the one-line errors
(``UsageError``, ``USAGE_ERRORS``, ``unknown_option``, ``fail``) and the task list of the help
texts. Kept apart so that each command module can use them without importing the others."""

from __future__ import annotations

import argparse
import errno
import os
import sys
from typing import Any

#: what a command may raise for bad input: reported as ``rrls <command>: <message>``, exit 2
USAGE_ERRORS = (ValueError, FileNotFoundError, FileExistsError, NotADirectoryError)


class Parser(argparse.ArgumentParser):
    """``argparse`` without abbreviations: ``--learning-start`` must not silently mean
    ``--learning-starts`` (a typo would train with a value nobody chose). Subcommands inherit
    it; ``subcommands`` maps each name to its parser, for ``unknown_option``."""

    subcommands: dict[str, argparse.ArgumentParser]

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        kwargs.setdefault("allow_abbrev", False)
        super().__init__(*args, **kwargs)

    def error(self, message: str) -> Any:
        """One line, exit status 2 (argparse's usage block is what ``--help`` is for)."""
        self.exit(2, f"{self.prog}: error: {message}\n")


def unknown_option(parser: argparse.ArgumentParser, command: str, extras: list[str]) -> str:
    """One line for options ``rrls COMMAND`` does not know, with the closest valid flag."""
    import difflib
    import re

    flag = extras[0].split("=", 1)[0]
    if not flag.startswith("-"):
        return f"rrls {command}: error: unexpected argument {flag!r}; see rrls {command} --help"
    options = sorted(set(re.findall(r"--[\w-]+", parser.format_help())))
    close = difflib.get_close_matches(flag, options, n=1, cutoff=0.75)
    hint = f" (did you mean {close[0]}?)" if close else ""
    return f"rrls {command}: error: unknown option {flag}{hint}; see rrls {command} --help"


class UsageError(ValueError):
    """Bad command-line input found after parsing (reported on one line, exit status 2)."""


def fail(command: str, message: str) -> int:
    """``rrls COMMAND: error: MESSAGE`` on stderr; the exit status 2 to return."""
    print(f"rrls {command}: error: {message}", file=sys.stderr)
    return 2


#: every command's arguments that name a file or directory, as its usage line shows them
PATH_ARGUMENTS = {
    "out": "--out",
    "dir": "DIR",
    "run_dir": "RUN_DIR",
    "bench_dir": "BENCH_DIR",
    "policy": "POLICY",
    "adversary": "--adversary",
    "reference": "--reference",
    "export_reference": "--export-reference",
    "protocol": "--protocol",
}


def refuse_link_loops(args: argparse.Namespace) -> None:
    """A path argument that runs into a loop of symbolic links is a one-line ``UsageError``,
    in every command alike: left to the command, Python 3.11's ``Path.resolve`` raised a
    ``RuntimeError`` traceback and other calls said ``File exists`` or ``no such file``."""
    for dest, name in PATH_ARGUMENTS.items():
        given = getattr(args, dest, None)
        for value in given if isinstance(given, list) else [given]:  # `report DIR DIR ...`
            if not isinstance(value, str) or not value:
                continue
            try:
                os.stat(value)
            except OSError as err:
                if err.errno == errno.ELOOP:
                    raise UsageError(
                        f"{name} {value}: a loop of symbolic links (too many levels); valid: a "
                        "path whose links end at a file or directory, or at nothing yet"
                    ) from None


def task_keys() -> list[str]:
    """Every registered task (the plug-ins' too, once ``main`` has loaded them)."""
    from rrls.tasks import TASKS

    return list(TASKS)


__all__ = [
    "PATH_ARGUMENTS",
    "USAGE_ERRORS",
    "Parser",
    "UsageError",
    "fail",
    "refuse_link_loops",
    "task_keys",
    "unknown_option",
]
