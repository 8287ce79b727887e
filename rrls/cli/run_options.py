"""A run's settings and an evaluation's protocol as command-line options, generated from the
dataclasses that hold them: the flag, the type, the choices, the help and the default come from
the field (``TrainConfig``'s ``hp`` metadata, ``Protocol``'s), once, for ``rrls train`` (every
setting), ``rrls benchmark`` (the settings and protocol fields a benchmark gives all its runs,
their default the preset's) and ``rrls evaluate`` (the protocol's, their default its own).
Torch-free: ``rrls benchmark --help`` runs without torch."""

from __future__ import annotations

import argparse
import typing
from dataclasses import fields
from typing import Any

from rrls.agents.config import TrainConfig
from rrls.algorithms import algorithm_key
from rrls.argtypes import recheck_value, seed_value, step_count, task_key
from rrls.evaluation.protocol import Protocol

#: integer options that count env steps: they accept 1e4, 100k, 1.5M (``argtypes.step_count``)
STEP_OPTIONS = frozenset(
    {"steps", "learning_starts", "eval_every", "checkpoint_every", "phase_steps", "buffer_size"}
)
#: how an option names its value where the type does not say it
METAVARS = {
    "uncertainty": "SET",
    "split": "extrapolation[:F]",
    "device": "{cpu,cuda,cuda:N}",
    **dict.fromkeys(STEP_OPTIONS, "N"),
}


def option_kind(hint: Any) -> Any:
    """The option's element type from a field's annotation (``int | None`` -> int)."""
    args = [a for a in typing.get_args(hint) if a is not type(None)]
    if typing.get_origin(hint) is tuple:
        return (tuple, args[0])
    if args:
        return option_kind(args[0])
    return hint


def add_option(parser: argparse._ActionsContainer, name: str, kind: Any, **kwargs: Any) -> None:
    """``--name`` of type ``kind`` (steps in any spelling, seeds, tasks and algorithms by their
    argument types; a bool as ``--name/--no-name``; a tuple as several values)."""
    flag = "--" + name.replace("_", "-")
    if kind is int and name in STEP_OPTIONS:
        kind = step_count
    elif kind is int and name == "seed":
        kind = seed_value
    elif name == "task":  # every spelling any command takes (InvertedPendulum, walker2d)
        kind = task_key
    elif name == "algo":  # TD3, NR-MDP, sac_dr: the table's names in any spelling
        kind = algorithm_key
    if kind is bool:
        parser.add_argument(flag, action=argparse.BooleanOptionalAction, **kwargs)
    elif isinstance(kind, tuple):
        parser.add_argument(flag, type=kind[1], nargs="+", metavar="N", **kwargs)
    else:
        parser.add_argument(flag, type=kind, **kwargs)


def add_run_options(
    parser: argparse._ActionsContainer,
    names: tuple[str, ...],
    default: str,
    notes: dict[str, str] | None = None,
    source: type = TrainConfig,
) -> None:
    """``source``'s fields ``names`` (a run's settings, ``TrainConfig``; or a benchmark's own,
    ``Benchmark``) as options whose default is given elsewhere (``None`` when not given;
    ``default`` says whose), each field's help with ``notes``' addition."""
    hints = typing.get_type_hints(source)
    by_name = {f.name: f for f in fields(source)}
    for name in names:
        f = by_name[name]
        text = f.metadata.get("help", "")
        if notes and name in notes:
            text += f"; {notes[name]}"
        kwargs: dict[str, Any] = {"default": None, "help": f"{text} (default: {default})"}
        if f.metadata.get("choices"):
            kwargs["choices"] = f.metadata["choices"]
        elif name in METAVARS:
            kwargs["metavar"] = METAVARS[name]
        add_option(parser, name, option_kind(hints[name]), **kwargs)


#: how a protocol option's value is read where it is not a count (``int``)
PROTOCOL_TYPES: dict[str, Any] = {"rate_limit": float, "recheck": recheck_value}


def add_protocol_options(
    parser: argparse._ActionsContainer,
    names: tuple[str, ...],
    default: str | None = None,
    prefix: str = "",
    convert: Any = int,
    notes: dict[str, str] | None = None,
) -> None:
    """``Protocol``'s fields ``names`` as options (values through ``PROTOCOL_TYPES``, else
    ``convert``): their help and metavar the field's, after ``prefix``, with ``notes``'
    addition; their default the protocol's own, or, where ``default`` says whose it is (a
    benchmark's preset), ``None`` when not given."""
    by_name = {f.name: f for f in fields(Protocol)}
    for name in names:
        f = by_name[name]
        paper = f"the paper's {f.default}"
        if f.default is None:
            paper = f"the paper's: {f.metadata.get('none', 'none')}"
        shown = f.default if default is None else f"{default}; {paper}"
        text = f.metadata["help"] + (f"; {notes[name]}" if notes and name in notes else "")
        parser.add_argument(
            "--" + name.replace("_", "-"),
            type=PROTOCOL_TYPES.get(name, convert),
            metavar=f.metadata.get("metavar", "N"),
            default=f.default if default is None else None,
            help=f"{prefix}{text} (default: {shown})",
        )


__all__ = [
    "METAVARS",
    "PROTOCOL_TYPES",
    "STEP_OPTIONS",
    "add_option",
    "add_protocol_options",
    "add_run_options",
    "option_kind",
]
