"""``rrls train``'s options, generated from the dataclasses — never a second copy of a default.

Run options come from ``TrainConfig``; hyper-parameters from every algorithm's ``Config``
(``--learning-rate``, ``--alpha``, ``--phase-steps``, ...). A hyper-parameter option defaults to
"the algorithm's own value" and its help lists those values; giving one that the chosen
algorithm does not have is refused, naming the algorithms that have it.

It imports the algorithms' dataclasses, hence torch: ``rrls.cli.app`` adds these options only for
``rrls train``, so that ``rrls --help`` and the other commands run without torch.
"""

from __future__ import annotations

import argparse
import typing
from dataclasses import fields, replace
from pathlib import Path
from typing import Any

from rrls.agents.config import TrainConfig
from rrls.agents.lookup import algorithm
from rrls.algorithms import built_in
from rrls.argtypes import worker_count, workers_help
from rrls.cli.run_options import add_option, option_kind
from rrls.deprecation import DeprecatedOption
from rrls.files import loads_json
from rrls.schema import JsonError
from rrls.seeds import EXAMPLES, parse_seeds

_SKIP = {"progress", "hyper"}


def _algos(args: argparse.Namespace | None = None) -> list[str]:
    """The built-in algorithms, plus the one named on the command line if it is a plug-in."""
    extra = getattr(args, "algo", None)
    return [*built_in(), *([extra] if extra and extra not in built_in() else [])]


def hyperparameter_table(algos: list[str] | None = None) -> dict[str, dict[str, Any]]:
    """name -> {"kind", "help", "choices", "defaults": {algo: default}} over the algorithms."""
    table: dict[str, dict[str, Any]] = {}
    for algo in algos or built_in():
        cls = algorithm(algo).Config
        hints = typing.get_type_hints(cls)
        for f in fields(cls):
            entry = table.setdefault(
                f.name,
                {
                    "kind": option_kind(hints[f.name]),
                    "help": f.metadata.get("help", ""),
                    "choices": f.metadata.get("choices"),
                    "defaults": {},
                },
            )
            entry["defaults"][algo] = f.default
    return table


def _show(value: Any) -> str:
    return " ".join(map(str, value)) if isinstance(value, tuple) else str(value)


def add_train_arguments(parser: argparse.ArgumentParser) -> None:
    """Every ``TrainConfig`` field and every algorithm hyper-parameter, as options."""
    from rrls.tasks import TASKS

    hints = typing.get_type_hints(TrainConfig)
    run = parser.add_argument_group("the run")
    for f in fields(TrainConfig):
        if f.name in _SKIP:
            continue
        kwargs: dict[str, Any] = {"default": None, "help": f.metadata.get("help", "")}
        if "default_text" in f.metadata:  # a default a value cannot show (None: the task's...)
            kwargs["help"] += f"; default: {f.metadata['default_text']}"
        if f.name in ("algo", "task"):
            kwargs["required"] = True
            if f.name == "task":
                kwargs["metavar"] = "TASK"
                kwargs["help"] += f" (one of {', '.join(TASKS)})"
        elif f.name == "uncertainty":  # any set the task declares: TrainConfig checks it
            kwargs["metavar"] = "SET"
        elif f.metadata.get("choices"):
            kwargs["choices"] = f.metadata["choices"]
            kwargs["help"] += f" (default {f.default})"
        elif f.default is not None and not isinstance(f.default, bool):
            kwargs["help"] += f" (default {f.default})"
        if isinstance(f.default, bool):
            run.add_argument(
                "--" + f.name.replace("_", "-"),
                action=argparse.BooleanOptionalAction if f.default else "store_true",
                default=None if f.default else False,
                help=kwargs["help"],
            )
            continue
        if f.name == "seed":  # one meaning in every command: a training seed
            kwargs["help"] = (
                "the training seed: every random draw of the run flows from it, each purpose a "
                f"child of SeedSequence(seed) (default {f.default})"
            )
        if f.name == "env_workers":  # one name and one meaning in every command
            kwargs["help"] = workers_help(
                "0 on a CPU, where the update dominates; on a GPU one per 4 envs of a group of 16 "
                "or more runs, within the cores",
                "stepping the envs of runs trained together",
            )
            run.add_argument("--workers", dest=f.name, type=worker_count, metavar="N", **kwargs)
            run.add_argument(
                "--env-workers",
                dest=f.name,
                type=worker_count,
                action=DeprecatedOption,
                new="--workers",
            )
            continue
        add_option(run, f.name, option_kind(hints[f.name]), **kwargs)
    run.add_argument("--resume", action="store_true", help="continue the run in --out exactly")
    run.add_argument(
        "--seeds",
        metavar="SEEDS",
        default=None,
        help=f"train several training seeds together in one process instead of --seed: {EXAMPLES} "
        "(a lone 3 is seed 3). "
        "The runs are stacked into one batched agent whose envs step in lockstep, and each run "
        "gets exactly the numbers it gets trained alone; faster on a GPU, which updates every "
        "seed at once (on a CPU the runs share the process's cores, so each gets a share). "
        "Each run's directory: the default per-seed name, or --out DIR/seed<S>. --resume and "
        "--overwrite apply to every run",
    )
    run.add_argument(
        "--hyper",
        action="append",
        metavar="NAME=VALUE",
        help="a hyper-parameter of a plug-in algorithm (--algo package.module:Learner) that has "
        "no option of its own (VALUE read as JSON, else as text)",
    )

    hyper = parser.add_argument_group(
        "hyper-parameters (default: the algorithm's paper value, shown per algorithm)"
    )
    for name, entry in hyperparameter_table().items():
        defaults = entry["defaults"]
        values = set(map(_show, defaults.values()))
        if len(values) == 1 and len(defaults) == len(built_in()):
            shown = f"default {values.pop()}"
        else:
            shown = ", ".join(f"{a}: {_show(v)}" for a, v in defaults.items())
        kwargs = {"default": None, "help": f"{entry['help']} ({shown})"}
        if entry["choices"]:
            kwargs["choices"] = entry["choices"]
        add_option(hyper, name, entry["kind"], **kwargs)


def configs_from_args(args: argparse.Namespace) -> tuple[list[TrainConfig], bool]:
    """The runs (and ``--resume``) the parsed options describe: one per seed of ``--seeds``
    (each in its default directory, or ``--out``/seed<S>), else the one run of ``--seed``."""
    if getattr(args, "seeds", None) is None:
        config, resume = config_from_args(args)
        return [config], resume
    if args.seed is not None:
        raise ValueError("--seed and --seeds are exclusive: give one seed or a set of seeds")
    seeds = parse_seeds(args.seeds)
    base, resume = config_from_args(args)
    configs = [
        replace(base, seed=s, out=None if args.out is None else str(Path(args.out) / f"seed{s}"))
        for s in seeds
    ]
    return configs, resume


def config_from_args(args: argparse.Namespace) -> tuple[TrainConfig, bool]:
    """The ``TrainConfig`` (and ``--resume``) the parsed options describe."""
    table = hyperparameter_table(_algos(args))
    hyper = {}
    for name, entry in table.items():
        value = getattr(args, name, None)
        if value is None:
            continue
        if args.algo not in entry["defaults"]:
            owners = ", ".join(entry["defaults"])
            flag = "--" + name.replace("_", "-")
            raise ValueError(f"{flag} does not apply to {args.algo} (only to {owners})")
        hyper[name] = tuple(value) if isinstance(entry["kind"], tuple) else value
    for item in getattr(args, "hyper", None) or []:  # a plug-in's own: --hyper name=value
        name, sep, text = item.partition("=")
        if not sep:
            raise ValueError(f"--hyper {item!r}: write NAME=VALUE")
        try:
            hyper[name] = loads_json(text, f"--hyper {name}")
        except JsonError as err:  # not JSON: text; too deep or too large: refused
            if not err.syntax:
                raise
            hyper[name] = text
    run = {
        f.name: getattr(args, f.name)
        for f in fields(TrainConfig)
        if f.name not in ("progress", "hyper") and getattr(args, f.name, None) is not None
    }
    # the command shows its progress: a bar on a terminal, plain lines in a log (rrls._progress)
    return TrainConfig(**run, hyper=hyper, progress=True), bool(args.resume)


__all__ = [
    "add_train_arguments",
    "config_from_args",
    "configs_from_args",
    "hyperparameter_table",
]
