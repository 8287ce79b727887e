"""``rrls train``: one run, or several seeds stacked in one process (the library's
:func:`rrls.agents.train` and :func:`rrls.agents.train_group`). Its options are generated from
the dataclasses in :mod:`rrls.cli.train_options`, which needs torch: this module does not
import it until the command runs, so ``rrls --help`` works without the ``train`` extra."""

from __future__ import annotations

import argparse
import shlex
import sys
from typing import Any

NAME = "train"


def _plugin_names() -> str:
    """`` (name, name)`` of the installed plug-in algorithms (entry point ``rrls.algorithms``)."""
    from rrls.algorithms import plugin_entry_points

    names = list(plugin_entry_points())
    return f" ({', '.join(names)})" if names else ""


def add_parser(sub: argparse._SubParsersAction) -> argparse.ArgumentParser:
    """Register ``rrls train`` on the ``rrls`` sub-command parser, without its options (they
    need torch: :func:`rrls.cli.train_options.add_train_arguments` adds them)."""
    from rrls.algorithms import built_in

    tr = sub.add_parser(
        NAME,
        help=f"train a baseline ({', '.join(built_in())}) or a plug-in{_plugin_names()}; needs "
        "the `train` extra",
        description="Train a baseline with the paper's hyper-parameters. Checkpoints are written "
        "to --out; --resume continues a killed run exactly where it stopped.",
    )
    return tr


def run(args: argparse.Namespace) -> int:
    """Train; exit status 3 when interrupted (the run continues with --resume)."""
    from rrls.agents import Interrupted, train, train_group
    from rrls.cli.train_options import configs_from_args
    from rrls.interrupts import keeping

    configs, resume = configs_from_args(args)  # bad options: ValueError, one line from main()
    with keeping(lambda: _checkpoints_kept(configs)):
        try:
            if args.seeds is None:
                run_dirs = [train(configs[0], resume=resume)]
            else:  # one process, the seeds stacked (same numbers as each alone)
                run_dirs = train_group(configs, resume=resume)
        except Interrupted as stop:
            print(f"{stop}; continue with --resume")
            return 3
        _print(args, configs, run_dirs)
    return 0


def _checkpoints_kept(configs: list[Any]) -> tuple[str, bool]:
    """What an interrupted ``rrls train`` keeps, read from its run directories: the step of
    each checkpoint (``--resume`` goes on from it: the interrupted step itself when the loop
    wrote one at Ctrl-C), or that none was written yet."""
    from pathlib import Path

    from rrls.agents.run import INTERRUPTED_KEY, read_checkpoint
    from rrls.rundir import CHECKPOINT

    at: dict[str, list[str]] = {}
    for config in configs:
        path = Path(config.out) / CHECKPOINT
        if not path.exists():
            continue
        try:
            state = read_checkpoint(path)
            step = f"step {int(state['step']):,} of {config.steps:,}"
            if state.get(INTERRUPTED_KEY):  # written at this Ctrl-C: nothing trained is lost
                step = f"the interrupted {step}"
        except (OSError, ValueError) as err:
            step = f"an unreadable step ({err})"
        at.setdefault(step, []).append(str(config.out))
    if not at:  # the same command starts the run again
        dirs = ", ".join(str(c.out) for c in configs)
        first = configs[0].checkpoint_every
        return f"no checkpoint yet (the first at step {first:,}): nothing kept in {dirs}", False
    kept = [
        f"the checkpoint{'s' if len(dirs) > 1 else ''} at {step} "
        f"{'are' if len(dirs) > 1 else 'is'} kept in {', '.join(dirs)}"
        for step, dirs in at.items()
    ]
    return "; ".join(kept), True


def _print(args: argparse.Namespace, configs: list[Any], run_dirs: list[Any]) -> None:
    """What was trained, and how to evaluate it."""
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
        return
    run_dir = run_dirs[0]
    print(
        f"trained {config.algo} on {config.task}/{config.uncertainty}: {run_dir}/policy.npz "
        f"(evaluate with: rrls evaluate {shlex.quote(str(run_dir))})"
    )
    if (run_dir / "adversary.npz").exists():
        print(f"against its own adversary (paper Table 6): rrls evaluate-dynamic {run_dir}")


def _warm_up(run_dir: Any) -> int | None:
    """The run's random warm-up (``learning_starts``) as its ``run.json`` records it."""
    from rrls.rundir import read_run_json

    try:
        hyper = read_run_json(run_dir)["config"]["hyper"]
        return int(hyper["learning_starts"])
    except (OSError, ValueError, KeyError, TypeError):
        return None


__all__ = ["NAME", "add_parser", "run"]
