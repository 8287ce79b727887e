"""``rrls benchmark``, ``rrls report``, ``rrls submit`` (and ``rrls quickstart``, the ``quick``
preset).

Bad specifications end with one line on stderr and exit status 2, before any run starts.
"""

from __future__ import annotations

import argparse
import shlex
import sys
from typing import Any

from rrls.deprecation import notice
from rrls.experiments.arguments import CONFIRM_ABOVE
from rrls.experiments.spec import PRESETS, SpecError
from rrls.extras import install_hint
from rrls.seeds import as_range, count_form, parse_seeds


def _fail(command: str, message: str) -> int:
    print(f"rrls {command}: error: {message}", file=sys.stderr)
    return 2


def run(args: argparse.Namespace) -> int:
    """Dispatch ``benchmark`` / ``report`` / ``submit`` / ``quickstart``; spec errors -> one
    line, exit 2."""
    if args.command == "submit":  # no SciPy needed
        return _submit(args)
    if args.command == "withdraw":
        return _withdraw(args)
    try:
        import scipy  # noqa: F401
    except ImportError:
        return _fail(args.command, f"the report needs SciPy: {install_hint('train')}")
    try:
        if args.command == "report":
            return _report(args)
        if args.command == "quickstart":
            return _quickstart(args)
        return _benchmark(args)
    except SpecError as err:
        return _fail(args.command, str(err))


def _spec_from(args: argparse.Namespace) -> tuple:
    from rrls.experiments.cpu_estimate import default_jobs
    from rrls.experiments.spec import make_spec

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


def _benchmark(args: argparse.Namespace) -> int:
    spec, jobs = _spec_from(args)
    if args.backend == "ray":
        try:
            import ray  # noqa: F401
        except ImportError:
            return _fail("benchmark", f"--backend ray needs Ray: {install_hint('ray')}")
    try:
        import torch  # noqa: F401
    except ImportError:
        return _fail("benchmark", f"training needs torch: {install_hint('train')}")
    from pathlib import Path

    from rrls.agents import algorithm
    from rrls.experiments.spec import BUILT_IN

    for name in spec.algos:  # a plug-in that is no learner: one line now, not in a worker
        if name not in BUILT_IN:
            try:
                algorithm(name)
            except ValueError as err:
                return _fail("benchmark", str(err))

    out = Path(args.out)
    if out.exists() and not out.is_dir():  # the real run refuses it: so does the dry run
        return _fail("benchmark", f"--out {out} is a file, not a directory: choose another --out")
    if args.dry_run:
        return _dry_run(out, spec, jobs or 0, args.backend, args.pack)
    todo, _ = _pending(Path(args.out), spec)
    if not confirmed("benchmark", len(todo), args.yes):
        return 1

    from rrls.experiments.runner import benchmark

    code = benchmark(args.out, spec, jobs or 0, args.backend, args.ray_address, pack=args.pack)
    if code in (0, 1) and (Path(args.out) / "report" / "summary.json").exists():
        print(_table(args.out))
    return code


def _dry_run(root: Any, spec: Any, jobs: int, backend: str, pack: int | None) -> int:
    """What ``rrls benchmark`` would do in ``root``, without doing any of it."""
    from rrls.experiments.benchfile import reconcile
    from rrls.experiments.pipeline import default_pack, groups
    from rrls.experiments.runner import plan

    spec, (todo, finished) = reconcile(root, spec), _pending(root, spec)
    pack = default_pack(spec, pack)
    print(plan(root, spec, len(todo), finished, jobs, backend, pack))
    print(f"\nruns to start, in order ({len(todo)}):")
    for i, group in enumerate(groups(todo, pack), 1):
        names = ", ".join(key.name(spec.uncertainty) for key in group)
        print(f"  {i:>4}. {names}")
    print(
        f"\nlayout: {root}/benchmark.json (the protocol), {root}/runs/<run>/ (policy.npz, "
        f"run.json, result.json, scalars.csv, eval/), {root}/results/ (the store), "
        f"{root}/report/ (report.md, tables/, figures/)\n(dry run: nothing written)"
    )
    return 0


def _pending(root: Any, spec: Any) -> tuple[list, int]:
    """(the runs ``root`` still lacks, how many it has) — without writing anything there."""
    from rrls.experiments.benchfile import reconcile
    from rrls.experiments.runner import pending_runs

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


def _report(args: argparse.Namespace) -> int:
    from pathlib import Path

    from rrls.experiments.benchfile import reporting, stored_fingerprints
    from rrls.experiments.reference import ReferenceError, export_reference
    from rrls.experiments.report import make_report
    from rrls.experiments.store import build_store

    root = Path(args.dir)
    if not (root / "runs").is_dir() and not (root / "results").is_dir():
        return _fail("report", f"{root} is not a benchmark directory (no runs/ or results/)")
    labels = {}
    for item in args.rename or []:
        name, sep, text = item.partition("=")
        if not sep or not name.strip() or not text.strip():
            return _fail(
                "report", f"--rename {item!r}: write NAME=TEXT (NAME@REF for a reference row)"
            )
        labels[name.strip()] = text.strip()
    try:
        with reporting(root):  # one store and report at a time (a benchmark ending, too)
            if (root / "runs").is_dir():
                build_store(root, stored_fingerprints(root))
            path = make_report(
                root, plots=not args.no_plots, reference=args.reference, labels=labels or None
            )
            exported = None
            if args.export_reference:
                exported = export_reference(root, args.export_reference, label=args.label)
    except ReferenceError as err:
        return _fail("report", str(err))
    print(_table(root))
    print(f"report: {path}")
    if exported is not None:
        print(
            f"reference: {args.export_reference} ({exported.label!r}: "
            f"{len(exported.rows)} cells; `rrls report DIR --reference "
            f"{shlex.quote(str(args.export_reference))}`)"
        )
    return 0


def _table(root: object) -> str:
    """The worst / average case per task and algorithm, the reference's rows too (the
    report's ``summary.json``, as ``rrls.experiments.report.terminal_table`` prints it)."""
    import json
    from pathlib import Path

    from rrls.experiments.report import terminal_table

    return terminal_table(json.loads((Path(str(root)) / "report" / "summary.json").read_text()))


def _quickstart(args: argparse.Namespace) -> int:
    """The ``quick`` preset in ``--out``: one pipeline with ``rrls benchmark --preset quick``."""
    import shutil
    from pathlib import Path

    from rrls.experiments.cpu_estimate import default_jobs
    from rrls.experiments.spec import make_spec

    try:
        import torch  # noqa: F401
    except ImportError:
        return _fail("quickstart", f"needs torch: {install_hint('train')}")
    from rrls.experiments.runner import benchmark

    spec = make_spec("quick", steps=args.steps, seeds=quickstart_seeds(args))
    todo, _ = _pending(Path(args.out), spec)
    if not confirmed("quickstart", len(todo), getattr(args, "yes", False)):
        return 1
    code = benchmark(args.out, spec, default_jobs())
    root = Path(args.out)
    if (root / "report" / "summary.json").exists():
        print(_table(root))
        figure = root / "report" / "figures" / "returns_invertedpendulum.png"
        if figure.exists():
            shutil.copyfile(figure, root / "quickstart.png")
            print(f"plot: {root / 'quickstart.png'}")
        print(f"report: {root / 'report' / 'report.md'} (reduced budget, not the paper's)")
        print(f"runs: {root}/runs (TensorBoard: tensorboard --logdir {root}/runs)")
    return code


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


def _withdraw(args: argparse.Namespace) -> int:
    from rrls.experiments.submission import SubmitError
    from rrls.experiments.withdraw import remove_submission

    try:
        names = remove_submission(args.bench_dir, args.algo, args.task, args.seed)
    except SubmitError as err:
        return _fail("withdraw", str(err))
    print("withdrawn: " + ", ".join(names))
    print(f"report: rrls report {shlex.quote(str(args.bench_dir))}")
    return 0


def _submit(args: argparse.Namespace) -> int:
    from rrls.evaluation import PolicyError
    from rrls.experiments.submission import SubmitError, submit

    if args.workers is not None and args.workers < 0:
        return _fail("submit", f"--workers must be >= 0 (0: in this process), got {args.workers}")
    budget = {}
    for item in args.budget or []:
        key, sep, value = item.partition("=")
        if not sep or not key.strip():
            return _fail("submit", f"--budget {item!r}: write KEY=VALUE (e.g. 'gpu hours=3')")
        budget[key.strip()] = value.strip()
    try:
        done = submit(
            args.bench_dir,
            args.algo,
            args.task,
            args.seed,
            args.policy,
            adversary=args.adversary,
            overwrite=args.overwrite,
            game=args.game,
            alpha=args.alpha,
            preset=args.preset,
            workers=args.workers,
            progress=None,
            add_task=args.add_task,
            steps=args.steps,
            budget=budget,
        )
    except (SubmitError, PolicyError) as err:
        return _fail("submit", str(err))
    r = done.result
    what = "submitted" if done.evaluated else "already submitted (same policy; nothing to do)"
    print(
        f"{what}: {r['algorithm']} on {r['task']}/{r['uncertainty']} seed {r['seed']}: worst "
        f"case {r['worst_case']:,.2f}, average case {r['average_case']:,.2f}"
        + (f", against its adversary {r['dynamic_mean']:,.2f}" if "dynamic_mean" in r else "")
    )
    print(f"run: {done.run_dir}")
    print(f"report: rrls report {shlex.quote(str(args.bench_dir))}")
    return 0
