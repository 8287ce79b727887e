"""The ``rrls`` command line. Thin: it parses arguments and calls the library."""

from __future__ import annotations

import argparse
import shlex
import sys
from typing import Any

from rrls import argtypes
from rrls.argtypes import positive_int, seed_value, set_name, step_count, task_key
from rrls.extras import install_hint

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


def _task_keys() -> list[str]:
    from rrls.tasks import TASKS

    return list(TASKS)


def _plugin_names() -> str:
    """`` (name, name)`` of the installed plug-in algorithms (entry point ``rrls.algorithms``)."""
    from rrls.algorithms import plugin_entry_points

    names = list(plugin_entry_points())
    return f" ({', '.join(names)})" if names else ""


def build_parser(with_train: bool = True) -> argparse.ArgumentParser:
    from rrls import __version__
    from rrls.algorithms import built_in
    from rrls.seeds import EXAMPLES

    parser = Parser(
        prog="rrls",
        description="Robust Reinforcement Learning Suite. One vocabulary in every command: "
        f"--seed S is one seed, --seeds a list or range of seeds ({EXAMPLES}); --workers N the "
        "worker processes; --mesh N points per dimension; --physics v5|paper.",
    )
    parser.add_argument("--version", action="version", version=f"rrls {__version__}")
    sub = parser.add_subparsers(dest="command", required=True)

    check = sub.add_parser(
        "check",
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
        f"{', '.join(_task_keys())})",
    )
    check.add_argument(
        "--steps", type=positive_int, default=100, help="steps per episode (default: %(default)s)"
    )
    check.add_argument(
        "--seed",
        type=seed_value,
        default=0,
        help="seed of resets and actions (default: %(default)s)",
    )

    ev = sub.add_parser(
        "evaluate",
        help="evaluate a policy over a mesh of an uncertainty set (worst / average case)",
        description="Evaluate POLICY over a uniform mesh of the uncertainty set (paper §4). "
        "Re-running the same command with the same --out resumes an interrupted evaluation; "
        "a second evaluation into the same --out while one runs is refused.",
    )
    ev.add_argument(
        "policy",
        help="a policy file (.npz MLP), an `rrls train` run directory, a Stable-Baselines3 .zip "
        "or module:attribute (the last two run code from the file/module)",
    )
    ev.add_argument(
        "--task",
        type=task_key,
        metavar="TASK",
        help=f"one of {', '.join(_task_keys())} (default: the policy's own task, if recorded)",
    )
    ev.add_argument(
        "--uncertainty",
        type=set_name,
        default=None,
        help="the set to mesh: 1d, 2d, 3d (masses/friction), rarl (forces) or nominal (the "
        "model as shipped). Default: the set the policy was trained on, else 3d (2d for "
        "invertedpendulum)",
    )
    ev.add_argument(
        "--mesh", type=positive_int, default=10, help="points per dimension (default 10)"
    )
    ev.add_argument(
        "--episodes", type=positive_int, default=5, help="episodes per point (default 5)"
    )
    ev.add_argument(
        "--seed",
        type=seed_value,
        default=0,
        help="root of the per-episode seeds (default 0); results depend only on it",
    )
    ev.add_argument(
        "--workers",
        type=argtypes.worker_count,
        default=None,
        help="worker processes, at most 1024; 0: in this process (default: the number of "
        "cores; results do not depend on it)",
    )
    ev.add_argument(
        "--batch-size",
        type=positive_int,
        default=None,
        help="live episodes per worker (default: the engine's; results do not depend on it)",
    )
    ev.add_argument(
        "--no-endpoint",
        action="store_true",
        help="the original code's np.arange mesh (upper bounds excluded)",
    )
    ev.add_argument(
        "--physics",
        choices=["v5", "paper"],
        default=None,
        help="v5 (Gymnasium v5, rrls's parameter semantics) or paper (the paper's Gymnasium v5 "
        "envs, the original code's parameter writes, np.arange mesh); default: the physics the "
        "policy was trained on (rrls train records it), else v5",
    )
    ev.add_argument(
        "--split",
        metavar="KIND[:F]",
        default=None,
        help="also give in- and out-of-distribution worst/average case: extrapolation[:F] (ID: "
        "the centred box, a fraction F of each axis, default 0.5) or interpolation[:F] (ID: the "
        "set minus that box); default: the split the run trained under (rrls train --split)",
    )
    ev.add_argument(
        "--out",
        help="output directory (default: evaluations/<policy>-<task>-<uncertainty>-mesh<M>-ep<E>"
        "-seed<S>)",
    )
    ev.add_argument("--plot", action="store_true", help="also write OUT/returns.png")

    tr = sub.add_parser(
        "train",
        help=f"train a baseline ({', '.join(built_in())}) or a plug-in{_plugin_names()}; needs "
        "the `train` extra",
        description="Train a baseline with the paper's hyper-parameters. Checkpoints are written "
        "to --out; --resume continues a killed run exactly where it stopped.",
    )
    if with_train:  # the options come from the dataclasses, which need torch: only for `train`
        from rrls.agents.options import add_train_arguments

        add_train_arguments(tr)

    ed = sub.add_parser(
        "evaluate-dynamic",
        help="a RARL / NR-MDP run's policy against its own trained adversary (paper Table 6)",
        description="Play a two-player run's final protagonist (policy.npz) against its own final "
        "adversary (adversary.npz) for --episodes episodes, in the game the run trained in "
        "(RARL's, TC-RMDP's rate-limited one, or NR-MDP's action mixing): the paper's Table 6.",
    )
    ed.add_argument("run_dir", help="an `rrls train` run directory holding adversary.npz")
    ed.add_argument(
        "--episodes", type=positive_int, default=10, help="episodes (default 10, the paper's)"
    )
    ed.add_argument(
        "--seed", type=seed_value, default=0, help="seed of the episodes' resets (default 0)"
    )
    ed.add_argument(
        "--workers",
        type=argtypes.worker_count,
        default=1,
        help="worker processes, at most 1024; 0: in this process (default 1; results do not "
        "depend on it)",
    )
    ed.add_argument(
        "--out",
        default=None,
        help="keep finished episodes in this directory; the same command again resumes",
    )

    quick = sub.add_parser(
        "quickstart",
        help="the `quick` benchmark preset: five algorithms on InvertedPendulum's 1D set, "
        "evaluated, reported, plotted (~18 min on 2 cores)",
        description="The README's main command: `rrls benchmark --preset quick` in --out. TD3, "
        "DR, M2TD3, RARL and NR-MDP on InvertedPendulum's 1D set, 3 seeds x 30 k steps with "
        "64-64 networks (a reduced protocol at which TD3 learns the nominal task on every seed), "
        "each evaluated over a 10-point mesh x 5 episodes, then the report, its tables and a "
        "plot. Resumable: the same command continues where it stopped.",
    )
    quick.add_argument(
        "--out", default="quickstart", help="output directory (default: %(default)s)"
    )
    quick.add_argument(
        "--steps",
        type=step_count,
        default=None,
        help="steps per run: 30000, 1e4, 100k (default: the preset's 30 000)",
    )
    quick.add_argument(
        "--seeds",
        metavar="SEEDS",
        default=None,
        help=f"the seeds, a list or range: {EXAMPLES} (default: the preset's 0-2)",
    )
    quick.add_argument("--seed", type=seed_value, default=None, help=argparse.SUPPRESS)
    quick.add_argument("--yes", action="store_true", help="start without asking (see benchmark)")

    from rrls.experiments.arguments import add_parsers

    add_parsers(sub)  # benchmark, report, submit, withdraw

    plot = sub.add_parser(
        "plot",
        help="plot a saved evaluation: return over the uncertainty set",
        description="Draw the mean return over the uncertainty set from an `rrls evaluate` "
        "output directory: a line (1D), a heatmap (2D) or three slices through the worst point "
        "on one colour scale (3D).",
    )
    plot.add_argument("dir", help="an `rrls evaluate` output directory")
    plot.add_argument("--out", help="PNG path (default: DIR/returns.png)")
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
    try:
        return _dispatch(args)
    except USAGE_ERRORS as err:
        print(f"rrls {args.command}: error: {err}", file=sys.stderr)
        return 2
    except (OSError, MemoryError) as err:  # the machine's, not the input's: still one line
        from rrls._io import resource_error

        print(f"rrls {args.command}: error: {resource_error(err)}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        from rrls.interrupts import interrupted

        print(interrupted(args.command, argv), file=sys.stderr)
        return 130


def _dispatch(args: argparse.Namespace) -> int:
    if args.command == "check":
        from rrls.check import main as check_main

        return check_main(args.task, args.steps, args.seed)
    if args.command == "evaluate":
        return _evaluate(args)
    if args.command == "train":
        return _train(args)
    if args.command == "evaluate-dynamic":
        return _evaluate_dynamic(args)
    if args.command in ("benchmark", "report", "submit", "withdraw", "quickstart"):
        from rrls.experiments.commands import run

        return run(args)
    if args.command == "plot":
        from pathlib import Path

        from rrls.evaluation.result_plot import plot_result

        if not Path(args.dir).is_dir():
            raise FileNotFoundError(f"no evaluation directory {args.dir}")
        print(plot_result(args.dir, args.out))
        return 0
    raise AssertionError(args.command)  # argparse rejects unknown commands


def _split_rows(result: Any, split: str | None) -> list[tuple[str, str]]:
    """In- and out-of-distribution worst/average case, when the evaluation had a split."""
    scores = result.split_scores()
    if not scores:
        return []

    def fmt(v: float | None) -> str:
        return "-" if v is None else f"{v:,.2f}"

    return [
        (
            label,
            f"worst {fmt(scores[f'worst_case_{tag}'])}, average "
            f"{fmt(scores[f'average_case_{tag}'])} over {scores[f'points_{tag}']} points",
        )
        for tag, label in (("id", f"in distribution ({split})"), ("ood", "out of distribution"))
    ]


def _evaluate(args: argparse.Namespace) -> int:
    from pathlib import Path

    from rrls.evaluation import Protocol, evaluate, load_policy
    from rrls.tasks import get_task

    policy = load_policy(args.policy)
    meta = getattr(policy, "metadata", {}) or {}
    task = args.task or meta.get("task")
    if task is None:
        raise UsageError("--task is required (the policy does not record its task)")
    task = get_task(task).key
    if meta.get("task") not in (None, task):
        raise UsageError(f"the policy was trained on {meta['task']!r}, not on --task {task!r}")
    protocol = Protocol.for_policy(
        meta,
        task,
        uncertainty=args.uncertainty,
        mesh=args.mesh,
        episodes=args.episodes,
        seed=args.seed,
        physics=args.physics,
        endpoint=False if args.no_endpoint else None,
        split=args.split,
    )
    uncertainty, physics, split_text = protocol.uncertainty, protocol.physics, protocol.split
    out = Path(
        args.out
        or f"evaluations/{_policy_name(args.policy)}-{task}-{uncertainty}-mesh{args.mesh}"
        f"-ep{args.episodes}-seed{args.seed}"
        + ("-paper" if physics == "paper" else "")
    )
    result = evaluate(
        policy,
        task,
        protocol=protocol,
        workers=args.workers,
        out_dir=out,
        batch_size=args.batch_size,
        progress=True,
    )
    summary = result.summary()
    worst = ", ".join(f"{k}={v:.4g}" for k, v in result.worst_point.items()) or "nominal model"
    rows = [
        ("task / set", f"{result.task} / {uncertainty} ({physics} physics)"),
        (
            "mesh",
            f"{len(result.per_point)} points ({args.mesh} per dimension) "
            f"x {args.episodes} episodes, seed {args.seed}",
        ),
        ("worst case", f"{result.worst_case:,.2f}   at {worst}"),
        ("average case", f"{result.average_case:,.2f}"),
        *_split_rows(result, split_text),
        ("diverged", f"{summary['diverged']} of {summary['episodes_total']} episodes"),
        ("written", f"{out / 'summary.json'}, {out / _table_file(out)}"),
    ]
    width = max(len(k) for k, _ in rows)
    for key, value in rows:
        print(f"{key:<{width}}  {value}")
    if args.plot:  # after the table: a refused plot (nominal: one point) loses no result
        from rrls.evaluation.result_plot import plot_result

        print(f"{'plot':<{width}}  {plot_result(out)}")
    return 0


def _train(args: argparse.Namespace) -> int:
    from rrls.agents import Interrupted, train, train_group
    from rrls.agents.options import configs_from_args

    configs, resume = configs_from_args(args)  # bad options: ValueError, one line from main()
    try:
        if args.seeds is None:
            run_dirs = [train(configs[0], resume=resume)]
        else:  # one process, the seeds stacked (same numbers as each alone)
            run_dirs = train_group(configs, resume=resume)
    except Interrupted as stop:
        print(f"{stop}; continue with --resume")
        return 3
    config = configs[0]
    warm_up = _warm_up(run_dirs[0])
    if warm_up is not None and config.steps <= warm_up:  # a policy nobody trained: say so
        print(
            f"rrls train: warning: --steps {config.steps} <= the warm-up of {warm_up} random "
            "steps (--learning-starts): no update was made and the policy is untrained",
            file=sys.stderr,
        )
    if args.seeds is not None:
        seeds = ", ".join(str(c.seed) for c in configs)
        print(f"trained {config.algo} on {config.task}/{config.uncertainty}, seeds {seeds}:")
        for run_dir in run_dirs:
            print(f"  {run_dir}/policy.npz")
        print("evaluate each with: rrls evaluate DIR")
        if (run_dirs[0] / "adversary.npz").exists():
            print("against its own adversary (paper Table 6): rrls evaluate-dynamic DIR")
        return 0
    run_dir = run_dirs[0]
    print(
        f"trained {config.algo} on {config.task}/{config.uncertainty}: {run_dir}/policy.npz "
        f"(evaluate with: rrls evaluate {shlex.quote(str(run_dir))})"
    )
    if (run_dir / "adversary.npz").exists():
        print(f"against its own adversary (paper Table 6): rrls evaluate-dynamic {run_dir}")
    return 0


def _policy_name(policy: str) -> str:
    """A folder-safe name for ``rrls evaluate``'s default output: a run directory's or file's
    name (``td3-hopper-3d-seed0``, ``agent``), or ``module.attr`` — so evaluating a second
    policy does not land in the first one's folder (refused there: another fingerprint)."""
    import re
    from pathlib import Path

    text = str(policy).rstrip("/")
    name = text.replace(":", ".") if ":" in text and not Path(text).exists() else Path(text).stem
    return re.sub(r"[^\w.-]+", "_", name)[:80] or "policy"


def _warm_up(run_dir: Any) -> int | None:
    """The run's random warm-up (``learning_starts``) as its ``run.json`` records it."""
    from rrls.rundir import read_run_json

    try:
        hyper = read_run_json(run_dir).get("hyperparameters") or {}
        return int(hyper["learning_starts"])
    except (OSError, ValueError, KeyError, TypeError):
        return None


def _evaluate_dynamic(args: argparse.Namespace) -> int:
    from rrls.evaluation import evaluate_run_dynamic

    result = evaluate_run_dynamic(
        args.run_dir, episodes=args.episodes, seed=args.seed, workers=args.workers, out_dir=args.out
    )
    print(f"{result.env_id}: {result.mean:.2f} ± {result.std:.2f} over {args.episodes} episodes")
    return 0


def _table_file(out: object) -> str:
    from pathlib import Path

    return "episodes.parquet" if (Path(str(out)) / "episodes.parquet").exists() else "episodes.csv"


__all__ = ["USAGE_ERRORS", "Parser", "UsageError", "build_parser", "main", "unknown_option"]


if __name__ == "__main__":
    sys.exit(main())
