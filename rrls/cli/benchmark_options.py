"""What the commands that start or report benchmark runs share (``rrls benchmark``, ``rrls
quickstart``, ``rrls report``): the spec from the options, the seeds' grammar, the question
before many runs start, the runs still to do, the table printed at the end, and the guard that
turns a missing SciPy or a bad specification into one line with exit status 2."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable
from typing import Any

from rrls.benchmark.grid import PRESETS, SpecError
from rrls.cli.parsing import fail
from rrls.extras import install_hint
from rrls.seeds import as_range, count_form, parse_seeds

#: more runs than this, started from a terminal without --yes, ask first
CONFIRM_ABOVE = 50


def guarded(args: argparse.Namespace, body: Callable[[argparse.Namespace], int]) -> int:
    """``body(args)`` for a command that ends in a report: without SciPy, or for a bad
    specification (``SpecError``), one line on stderr and exit status 2."""
    try:
        import scipy  # noqa: F401
    except ImportError:
        return fail(args.command, f"the report needs SciPy: {install_hint('train')}")
    try:
        return body(args)
    except SpecError as err:
        return fail(args.command, str(err))


def spec_from(args: argparse.Namespace) -> tuple:
    """The benchmark's spec and worker count from `rrls benchmark`'s options (checked here)."""
    from rrls.benchmark.cpu_estimate import default_jobs
    from rrls.benchmark.grid import make_spec

    if args.preset not in PRESETS:
        raise SpecError(f"unknown preset {args.preset!r}; valid: {', '.join(PRESETS)}")
    if args.backend not in ("local", "ray"):
        raise SpecError(f"unknown backend {args.backend!r}; valid: local, ray")
    if args.workers is not None and args.workers < 1:
        raise SpecError(
            f"--workers must be >= 1 here, got {args.workers} (each benchmark run has its own "
            "process: 0, 'in this process', does not apply)"
        )
    if getattr(args, "pack", None) is not None and args.pack < 1:
        raise SpecError(f"--pack must be >= 1, got {args.pack}")
    if args.device is not None and not (args.device == "cpu" or args.device.startswith("cuda")):
        raise SpecError(f"unknown device {args.device!r}; valid: cpu, cuda")
    spec = make_spec(
        args.preset,
        algos=args.algos,
        tasks=args.tasks,
        uncertainty=args.uncertainty.lower() if args.uncertainty else None,
        seeds=benchmark_seeds(args.seeds),
        steps=args.steps,
        learning_starts=args.learning_starts,
        eval_every=args.eval_every,
        mesh=args.mesh,
        episodes=args.episodes,
        device=args.device,
        physics=getattr(args, "physics", None),
        simulator=getattr(args, "simulator", None),
        rate_limit=getattr(args, "rate_limit", None),
        observe=getattr(args, "observe", None),
        split=getattr(args, "split", None),
        recheck=getattr(args, "recheck", None),
        protocol=getattr(args, "protocol", None),
    )
    jobs = args.workers or (None if args.backend == "ray" else default_jobs())
    return spec, jobs


def benchmark_seeds(text: str | None) -> list[int] | None:
    """``--seeds`` of ``rrls benchmark``: a list or range (:mod:`rrls.seeds`). A bare ``N`` was
    once a count of seeds here and one seed everywhere else: it is refused with the two ways to
    write what was meant (``N-N``: that seed alone)."""
    if text is None:
        return None
    count = count_form(text)
    if count is not None:
        many = (
            f"--seeds {as_range(list(range(count)))} for {count} seeds from 0, or " if count else ""
        )
        raise SpecError(
            f"--seeds {text}: a bare number is no longer a count of seeds here (it is one seed "
            f"in every command); write {many}--seeds {count}-{count} for seed {count} alone"
        )
    try:
        return parse_seeds(text)
    except ValueError as err:
        raise SpecError(str(err)) from None


def pending(root: Any, spec: Any) -> tuple[list, int]:
    """(the runs ``root`` still lacks, how many it has) — without writing anything there."""
    from rrls.benchmark.benchfile import reconcile
    from rrls.benchmark.runner import pending_runs

    return pending_runs(root, reconcile(root, spec))  # another protocol: refused now


def confirmed(command: str, runs: int, yes: bool) -> bool:
    """Whether to start ``runs`` runs: yes below ``CONFIRM_ABOVE``, with ``--yes``, without a
    terminal on stdin or under CI (never blocks a script); else the answer to a prompt."""
    import os

    if yes or runs <= CONFIRM_ABOVE or os.environ.get("CI") or not sys.stdin.isatty():
        return True
    prompt = f"rrls {command}: start {runs} runs (see --dry-run for the estimate)? [y/N] "
    try:
        answer = input(prompt)
    except (EOFError, KeyboardInterrupt):
        answer = ""
    if answer.strip().lower() in ("y", "yes"):
        return True
    print(f"rrls {command}: nothing started (--yes starts without asking)", file=sys.stderr)
    return False


def results_table(root: object) -> str:
    """The worst / average case per task and algorithm, the reference's rows too (the
    report's ``summary.json``, as ``rrls.report.writer.terminal_table`` prints it)."""
    from pathlib import Path

    from rrls.files import read_json
    from rrls.report.writer import terminal_table

    return terminal_table(read_json(Path(str(root)) / "report" / "summary.json"))


__all__ = [
    "CONFIRM_ABOVE",
    "benchmark_seeds",
    "confirmed",
    "guarded",
    "pending",
    "results_table",
    "spec_from",
]
