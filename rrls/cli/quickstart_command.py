"""``rrls quickstart``: the README's main command, ``rrls benchmark --preset quick`` in --out
with the report's table and a plot at the end. What it shares with ``rrls benchmark`` is in
:mod:`rrls.cli.benchmark_options`."""

from __future__ import annotations

import argparse
from typing import Any

from rrls.argtypes import seed_value, step_count
from rrls.benchmark.grid import SpecError
from rrls.cli.benchmark_options import confirmed, guarded, pending, results_table
from rrls.cli.parsing import fail
from rrls.deprecation import notice
from rrls.extras import install_hint
from rrls.seeds import EXAMPLES, as_range, parse_seeds

NAME = "quickstart"


def add_parser(sub: argparse._SubParsersAction) -> argparse.ArgumentParser:
    """Register ``rrls quickstart`` on the ``rrls`` sub-command parser."""
    quick = sub.add_parser(
        NAME,
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
        help=f"the training seeds, a list or range: {EXAMPLES} (default: the preset's 0-2)",
    )
    quick.add_argument("--seed", type=seed_value, default=None, help=argparse.SUPPRESS)
    quick.add_argument("--yes", action="store_true", help="start without asking (see benchmark)")
    return quick


def run(args: argparse.Namespace) -> int:
    """Run the preset; a bad input is one line, exit status 2."""
    return guarded(args, _quickstart)


def _quickstart(args: argparse.Namespace) -> int:
    """The ``quick`` preset in ``--out``: one pipeline with ``rrls benchmark --preset quick``."""
    from pathlib import Path

    from rrls.benchmark.cpu_estimate import default_jobs
    from rrls.benchmark.grid import make_spec

    try:
        import torch  # noqa: F401
    except ImportError:
        return fail("quickstart", f"needs torch: {install_hint('train')}")
    from rrls.benchmark.runner import benchmark, kept_runs
    from rrls.interrupts import keeping
    from rrls.report import make_report

    spec = make_spec("quick", steps=args.steps, seeds=quickstart_seeds(args))
    root = Path(args.out)
    with keeping(lambda: kept_runs(root, spec)):
        todo, _ = pending(root, spec)
        if not confirmed("quickstart", len(todo), getattr(args, "yes", False)):
            return 1
        code = benchmark(root, spec, default_jobs(), report=make_report)
        _show(root)
    return code


def _show(root: Any) -> None:
    """The report's table, the plot and where the rest is."""
    import shutil

    if (root / "report" / "summary.json").exists():
        print(results_table(root))
        figure = root / "report" / "figures" / "returns_invertedpendulum.png"
        if figure.exists():
            shutil.copyfile(figure, root / "quickstart.png")
            print(f"plot: {root / 'quickstart.png'}")
        print(f"report: {root / 'report' / 'report.md'} (reduced budget, not the paper's)")
        print(f"runs: {root}/runs (TensorBoard: tensorboard --logdir {root}/runs)")


def quickstart_seeds(args: argparse.Namespace) -> list[int] | None:
    """``--seeds`` (a list or range), or the deprecated ``--seed S`` (the first of three)."""
    first = getattr(args, "seed", None)
    text = getattr(args, "seeds", None)
    if first is not None and text is not None:
        raise SpecError("give --seeds only (--seed S is its deprecated spelling S-(S+2))")
    if first is not None:
        seeds = [first, first + 1, first + 2]
        notice("quickstart", f"--seed {first} is deprecated; write --seeds {as_range(seeds)}")
        return seeds
    try:
        return None if text is None else parse_seeds(text)
    except ValueError as err:
        raise SpecError(str(err)) from None


__all__ = ["NAME", "add_parser", "quickstart_seeds", "run"]
