"""``rrls benchmark``, ``rrls report``, ``rrls submit`` (and ``rrls quickstart``, the ``quick``
preset).

Bad specifications end with one line on stderr and exit status 2, before any run starts.
"""

from __future__ import annotations

import argparse
import sys
from typing import Any

from rrls.deprecation import DeprecatedOption, notice
from rrls.experiments.spec import ALGOS, BUILT_IN, PAPER_TASKS, PRESETS, SpecError
from rrls.seeds import EXAMPLES, as_range, count_form, parse_seeds

#: more runs than this, started from a terminal without --yes, ask first
CONFIRM_ABOVE = 50


def _plugins() -> str:
    """``(name, name) `` of the installed plug-in algorithms, for the help texts."""
    from rrls.algorithms import plugin_entry_points

    names = list(plugin_entry_points())
    return f"({', '.join(names)}) " if names else ""


def add_parsers(sub: argparse._SubParsersAction) -> None:
    """Register ``benchmark`` and ``report`` on the ``rrls`` sub-command parser (ranges are
    checked by the spec, so that errors are one line with exit status 2)."""
    from rrls.tasks import TASKS  # every registered task, plug-ins' included (loaded by main)

    b = sub.add_parser(
        "benchmark",
        help="train, evaluate and report a grid of runs (the paper's comparison); resumable",
        description="Run a grid (algorithm x task x seed): training, the final mesh evaluation, "
        "the dynamic evaluation of RARL/NR-MDP against their own adversaries; then the result "
        "store and the report under --out. Re-running the same command resumes; adding "
        "algorithms, tasks or seeds extends the benchmark. Explicit options override the preset.",
    )
    b.add_argument("--out", required=True, metavar="DIR", help="benchmark directory")
    b.add_argument(
        "--preset",
        default="paper",
        metavar="{" + ",".join(PRESETS) + "}",
        help="smoke (seconds, for tests), quick (~18 min on 2 cores, reduced protocol), "
        "hopper (~9.5 CPU-hours: the locomotion reference), paper (the paper's protocol); "
        "default: %(default)s (250 runs: try --dry-run first)",
    )
    b.add_argument(
        "--algos",
        help=f"comma-separated, of the built-in {', '.join(BUILT_IN)}, an installed plug-in "
        f"{_plugins()}or package.module:Learner (default: the preset's; the paper's five: "
        f"{','.join(ALGOS)})",
    )
    b.add_argument(
        "--tasks",
        help="comma-separated, of every registered task: "
        + ", ".join(TASKS)
        + " (default: the preset's; the paper's five: "
        + ", ".join(PAPER_TASKS)
        + ")",
    )
    b.add_argument(
        "--uncertainty",
        metavar="SET",
        help="evaluation set (and DR/M2TD3's training set): 1d, 2d, 3d (default: the preset's)",
    )
    b.add_argument(
        "--seeds",
        metavar="SEEDS",
        help=f"the seeds, a list or range: {EXAMPLES} (default: the preset's). A bare N "
        "(--seeds 3) is still read as N seeds 0..N-1, with a notice: deprecated, write 0-2",
    )
    b.add_argument(
        "--physics",
        choices=["v5", "paper"],
        help="v5 (default: Gymnasium v5, rrls's parameter semantics) or paper (the paper's "
        "Gymnasium v4 envs, the original code's parameter writes, np.arange mesh) for training and "
        "evaluation; recorded as given in benchmark.json",
    )
    b.add_argument(
        "--rate-limit",
        type=float,
        metavar="L",
        help="RARL trains against (and is evaluated with) TC-RMDP's time-constrained adversary, "
        "as its authors play it: each step it moves every parameter by at most L in raw "
        "parameter units (psi <- clip(psi + a * L, box); the authors train with 0.001), "
        "episodes start uniformly in the box, the adversary sees psi and the state",
    )
    b.add_argument(
        "--observe",
        choices=["vanilla", "stacked", "oracle"],
        help="with --rate-limit: RARL's protagonist is TC-RMDP's vanilla (the state; default), "
        "stacked (the previous state and action too) or oracle (the state and psi in [0, 1])",
    )
    b.add_argument(
        "--split",
        metavar="extrapolation[:F]",
        help="rrls's own extrapolation split: every run trains on the inner box of the set (a "
        "centred fraction F of each axis, default 0.5), the evaluation covers the whole set and "
        "rrls report gives in- and out-of-distribution worst/average case apart",
    )
    b.add_argument(
        "--steps", type=int, metavar="N", help="training steps per run (default: the preset's)"
    )
    b.add_argument(
        "--learning-starts",
        type=int,
        metavar="N",
        help="random steps before learning (default: the preset's; paper 25 000, quick 1 000; "
        "with --steps alone, at most a fifth of the budget)",
    )
    b.add_argument(
        "--eval-every",
        type=int,
        metavar="N",
        help="periodic evaluation every N steps (0: off; default: the preset's)",
    )
    b.add_argument(
        "--mesh",
        type=int,
        metavar="N",
        help="final evaluation: points per dimension (default: the preset's; paper 10)",
    )
    b.add_argument(
        "--episodes",
        type=int,
        metavar="N",
        help="final evaluation: episodes per point (default: the preset's; paper 5)",
    )
    b.add_argument(
        "--workers",
        type=int,
        metavar="N",
        help="worker processes: runs in parallel (default: the number of cores; Ray: the cluster)",
    )
    b.add_argument("--jobs", dest="workers", type=int, action=DeprecatedOption, new="--workers")
    b.add_argument(
        "--backend",
        default="local",
        metavar="{local,ray}",
        help="local (a process pool on this machine) or ray (a Ray cluster); default: %(default)s",
    )
    b.add_argument(
        "--ray-address", metavar="ADDR", help="Ray cluster address (default: RAY_ADDRESS or local)"
    )
    b.add_argument(
        "--device",
        metavar="{cpu,cuda,cuda:N}",
        help="cpu (default) or cuda (Ray: a quarter GPU per process)",
    )
    b.add_argument(
        "--dry-run",
        action="store_true",
        help="print the runs in the order they would start, the compute estimate and the "
        "output layout, then stop (nothing is written or trained)",
    )
    b.add_argument(
        "--pack",
        type=int,
        metavar="N",
        help="train up to N seeds of one algorithm and task together in one process (stacked "
        "agents, the same numbers as alone): the GPU then updates many seeds at once; on a CPU "
        "the runs of a process share its one thread. Default: every seed of a cell with "
        "--device cuda, 1 on cpu",
    )
    b.add_argument(
        "--yes",
        action="store_true",
        help=f"start without asking: from a terminal, more than {CONFIRM_ABOVE} runs to start "
        "ask for confirmation first (never asked without a terminal, or with CI set)",
    )

    r = sub.add_parser(
        "report",
        help="regenerate a benchmark's report (summary.json, report.md, tables, figures)",
        description="Rebuild DIR/results from the run directories and write DIR/report: "
        "summary.json, report.md, tables/*.tex (booktabs) and *.csv, figures.",
    )
    r.add_argument("dir", help="a `rrls benchmark --out` directory")
    r.add_argument("--no-plots", action="store_true", help="skip the figures")
    r.add_argument(
        "--reference",
        metavar="FILE",
        help="reference results (.json/.csv, or a shipped name: paper, quick) normalising"
        " the tasks without their own TD3 and M2TD3 runs; refused if measured under another"
        " protocol (physics, set, mesh, episodes)",
    )
    r.add_argument(
        "--export-reference",
        metavar="FILE",
        help="also write this benchmark's results (every algorithm, per-seed values) as a "
        "reference file (.json, or .csv) another lab can pass to --reference",
    )
    r.add_argument("--label", help="--export-reference: the reference's label")

    s = sub.add_parser(
        "submit",
        help="evaluate a policy trained elsewhere under a benchmark's protocol and add it as an "
        "algorithm (then `rrls report DIR` shows it beside the baselines)",
        description="Evaluate POLICY exactly as BENCH_DIR evaluates its own runs (same set, mesh, "
        "episodes and episode seeds; with --adversary also the dynamic evaluation) and store it "
        "as run (--algo, --task, --seed). POLICY: an rrls .npz, an `rrls train` run directory, a "
        "Stable-Baselines3 .zip or module:attribute naming a callable obs[B, d] -> act[B, k] (or "
        "an nn.Module / SB3 model). WARNING: an SB3 zip (cloudpickle) and module:attribute "
        "(import) run code from the file or module: submit only what you trust; rrls's own "
        ".npz and run directories are read without unpickling.",
    )
    s.add_argument("bench_dir", metavar="BENCH_DIR", help="a `rrls benchmark --out` directory")
    s.add_argument("policy", metavar="POLICY", help=".npz, run directory, SB3 .zip or mod:attr")
    s.add_argument("--algo", required=True, metavar="NAME", help="the algorithm's name in reports")
    s.add_argument("--task", required=True, metavar="TASK", help="one of the benchmark's tasks")
    s.add_argument("--seed", required=True, type=int, metavar="S", help="the policy's seed")
    s.add_argument(
        "--adversary", metavar="ADV_POLICY", help="also play this adversary (Table 6), same kinds"
    )
    s.add_argument(
        "--game",
        metavar="{adversarial,nr,pr}",
        help="the adversary's game: adversarial (picks the set's parameters; default unless an "
        "rrls adversary file records another), nr or pr (action-robust)",
    )
    s.add_argument("--alpha", type=float, help="nr/pr: the adversary's probability (default 0.1)")
    s.add_argument(
        "--overwrite", action="store_true", help="replace a submission made with another policy"
    )
    s.add_argument(
        "--preset",
        metavar="{" + ",".join(PRESETS) + "}",
        help="BENCH_DIR holds no benchmark yet: start one (no baselines) with this preset's "
        "protocol; compare with `rrls report BENCH_DIR --reference FILE`",
    )
    s.add_argument(
        "--workers",
        type=int,
        metavar="N",
        help="worker processes: the evaluation's (default: the number of cores)",
    )


def _fail(command: str, message: str) -> int:
    print(f"rrls {command}: error: {message}", file=sys.stderr)
    return 2


def run(args: argparse.Namespace) -> int:
    """Dispatch ``benchmark`` / ``report`` / ``submit`` / ``quickstart``; spec errors -> one
    line, exit 2."""
    if args.command == "submit":  # no SciPy needed
        return _submit(args)
    try:
        import scipy  # noqa: F401
    except ImportError:
        return _fail(args.command, "the report needs SciPy: pip install 'rrls[train]'")
    try:
        if args.command == "report":
            return _report(args)
        if args.command == "quickstart":
            return _quickstart(args)
        return _benchmark(args)
    except SpecError as err:
        return _fail(args.command, str(err))


def _spec_from(args: argparse.Namespace) -> tuple:
    from rrls.experiments.spec import default_jobs, make_spec

    if args.preset not in PRESETS:
        raise SpecError(f"unknown preset {args.preset!r}; valid: {', '.join(PRESETS)}")
    if args.backend not in ("local", "ray"):
        raise SpecError(f"unknown backend {args.backend!r}; valid: local, ray")
    if args.workers is not None and args.workers < 1:
        raise SpecError(f"--workers must be >= 1, got {args.workers}")
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
        rate_limit=getattr(args, "rate_limit", None),
        observe=getattr(args, "observe", None),
        split=getattr(args, "split", None),
    )
    jobs = args.workers or (None if args.backend == "ray" else default_jobs())
    return spec, jobs


def benchmark_seeds(text: str | None) -> list[int] | None:
    """``--seeds`` of ``rrls benchmark``: a list or range (:mod:`rrls.seeds`), or the deprecated
    count ``N`` (seeds 0..N-1, with a notice saying how to write it)."""
    if text is None:
        return None
    count = count_form(text)
    if count is None:
        try:
            return parse_seeds(text)
        except ValueError as err:
            raise SpecError(str(err)) from None
    if count < 1:
        raise SpecError(f"--seeds {text}: no seed to run (write the seeds: {EXAMPLES})")
    seeds = list(range(count))
    notice(
        "benchmark",
        f"--seeds {count} as a number of seeds is deprecated (it will mean seed {count} alone, "
        f"as in rrls train); write --seeds {as_range(seeds)}",
    )
    return seeds


def _benchmark(args: argparse.Namespace) -> int:
    spec, jobs = _spec_from(args)
    if args.backend == "ray":
        try:
            import ray  # noqa: F401
        except ImportError:
            return _fail("benchmark", "--backend ray needs Ray: pip install 'rrls[ray]'")
    try:
        import torch  # noqa: F401
    except ImportError:
        return _fail("benchmark", "training needs torch: pip install 'rrls[train]'")
    from pathlib import Path

    from rrls.agents import algorithm
    from rrls.experiments.spec import BUILT_IN

    for name in spec.algos:  # a plug-in that is no learner: one line now, not in a worker
        if name not in BUILT_IN:
            try:
                algorithm(name)
            except ValueError as err:
                return _fail("benchmark", str(err))

    if args.dry_run:
        return _dry_run(Path(args.out), spec, jobs or 0, args.backend, args.pack)
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

    from rrls.experiments.report import make_report
    from rrls.experiments.store import build_store

    root = Path(args.dir)
    if not (root / "runs").is_dir() and not (root / "results").is_dir():
        return _fail("report", f"{root} is not a benchmark directory (no runs/ or results/)")
    if (root / "runs").is_dir():
        build_store(root)
    from rrls.experiments.reference import ReferenceError, export_reference

    try:
        path = make_report(root, plots=not args.no_plots, reference=args.reference)
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
            f"{len(exported.rows)} cells; `rrls report DIR --reference {args.export_reference}`)"
        )
    return 0


def _table(root: object) -> str:
    """The worst / average case per task and algorithm, for the terminal."""
    import json
    from pathlib import Path

    summary = json.loads((Path(str(root)) / "report" / "summary.json").read_text())
    lines = [f"{'task':<18} {'algorithm':<10} {'seeds':>5} {'worst case':>20} {'average case':>20}"]
    from rrls.experiments.names import sort_algos

    for task, algos in summary["results"].items():
        for algo in sort_algos(algos):
            cell = algos[algo]
            w, a = cell["worst_case"], cell["average_case"]
            if not w["n_seeds"]:
                continue
            lines.append(
                f"{task:<18} {algo:<10} {w['n_seeds']:>5} "
                f"{w['mean']:>11.1f} ± {w['std']:<6.1f} {a['mean']:>11.1f} ± {a['std']:<6.1f}"
            )
    return "\n".join(lines)


def _quickstart(args: argparse.Namespace) -> int:
    """The ``quick`` preset in ``--out``: one pipeline with ``rrls benchmark --preset quick``."""
    import shutil
    from pathlib import Path

    from rrls.experiments.spec import default_jobs, make_spec

    try:
        import torch  # noqa: F401
    except ImportError:
        return _fail("quickstart", "needs torch: pip install 'rrls[train]'")
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


def _submit(args: argparse.Namespace) -> int:
    from rrls.evaluation import PolicyError
    from rrls.experiments.submission import SubmitError, submit

    if args.workers is not None and args.workers < 1:
        return _fail("submit", f"--workers must be >= 1, got {args.workers}")
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
        )
    except (SubmitError, PolicyError) as err:
        return _fail("submit", str(err))
    except OSError as err:  # the file system refuses a path (a name too long, no space, ...)
        where = f" ({str(err.filename)[:80]})" if err.filename else ""
        return _fail("submit", f"{err.strerror or err}{where}")
    r = done.result
    what = "submitted" if done.evaluated else "already submitted (same policy; nothing to do)"
    print(
        f"{what}: {r['algorithm']} on {r['task']}/{r['uncertainty']} seed {r['seed']}: worst "
        f"case {r['worst_case']:,.2f}, average case {r['average_case']:,.2f}"
        + (f", against its adversary {r['dynamic_mean']:,.2f}" if "dynamic_mean" in r else "")
    )
    print(f"run: {done.run_dir}")
    print(f"report: rrls report {args.bench_dir}")
    return 0
