"""The ``rrls`` command line (the console script ``rrls = rrls.cli:main``, and ``python -m rrls``).

Thin: it parses arguments and calls the library. ``app`` holds the top-level parser and ``main``,
``parsing`` what every command shares, and each command is one module, ``<name>_command``
(``add_parser`` and ``run``); ``train_options`` generates ``rrls train``'s options from the
dataclasses. This package only hands the entry points on.
"""

from rrls.cli.app import build_parser, main
from rrls.cli.parsing import USAGE_ERRORS, Parser, UsageError, unknown_option

__all__ = ["USAGE_ERRORS", "Parser", "UsageError", "build_parser", "main", "unknown_option"]
