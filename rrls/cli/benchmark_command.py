"""``rrls benchmark``: train, evaluate and report a grid of runs (the library's
:func:`rrls.benchmark.runner.benchmark`), or print what it would do (``--dry-run``). Its
options and what it does live here; what it shares with ``quickstart`` and ``report`` is in
:mod:`rrls.cli.benchmark_options`. Ranges are checked by the spec, so that errors are one line
with exit status 2."""

from __future__ import annotations

import argparse
from typing import Any

from rrls.argtypes import step_count, worker_count
from rrls.benchmark.grid import ALGOS, BUILT_IN, PAPER_TASKS, PRESETS, Benchmark
from rrls.cli.benchmark_options import (
    CONFIRM_ABOVE,
    confirmed,
    guarded,
    pending,
    results_table,
    spec_from,
)
from rrls.cli.parsing import fail
from rrls.cli.run_options import add_protocol_options, add_run_options
from rrls.deprecation import DeprecatedOption
from rrls.extras import install_hint
from rrls.seeds import EXAMPLES

NAME = "benchmark"
#: what a benchmark adds to a run setting's help (the rest is the TrainConfig field's)
NOTES = {
    "physics": "training and evaluation; recorded as given in benchmark.json",
    "device": "Ray: a quarter GPU per process",
    "rate_limit": "RARL also trains against it",
}


def _plugins() -> str:
    """``(name, name) `` of the installed plug-in algorithms, for the help texts."""
    from rrls.algorithms import plugin_entry_points

    names = list(plugin_entry_points())
    return f"({', '.join(names)}) " if names else ""


def _warmups() -> str:
    """The paper's five's warm-ups as the table declares them: the common one, then the rest by
    name (``25,000, M2TD3 100,000``)."""
    from collections import Counter

    from rrls.algorithms import ALGORITHMS, paper_five

    steps = {a: ALGORITHMS[a].learning_starts for a in paper_five()}
    common = Counter(steps.values()).most_common(1)[0][0]
    others = [f"{ALGORITHMS[a].display} {n:,}" for a, n in steps.items() if n != common]
    return ", ".join([f"{common:,}", *others])


def add_parser(sub: argparse._SubParsersAction) -> argparse.ArgumentParser:
    """Register ``rrls benchmark`` on the ``rrls`` sub-command parser."""
    from rrls.tasks import TASKS  # every registered task, plug-ins' included (loaded by main)

    b = sub.add_parser(
        NAME,
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
        "hopper-200k (~11 CPU-hours: the early-training locomotion reference), hopper (~67 "
        "CPU-hours: Hopper where TD3 hops, 700 k steps), halfcheetah (~27 "
        "CPU-hours: the locomotion reference where TD3 runs), paper (the "
        "paper's protocol); "
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
        "--seeds",
        metavar="SEEDS",
        help=f"the training seeds, a list or range: {EXAMPLES} (default: the preset's). A bare "
        "N, once a count of seeds here, is refused: write 0-2 for three seeds, 3-3 for seed 3",
    )
    # the dynamic evaluation's adversary, and RARL's protagonist in TC-RMDP's game: the
    # Protocol's and the Benchmark's fields, their help declared there
    add_protocol_options(b, ("rate_limit",), "the preset's", notes=NOTES)
    add_run_options(b, ("observe",), "the preset's; the paper's vanilla", source=Benchmark)
    # a run's settings every run of the benchmark shares: rrls train's options, from the same
    # TrainConfig fields (their help, type and choices), the default the preset's
    add_run_options(
        b,
        ("uncertainty", "split", "physics", "simulator", "steps", "eval_every", "device"),
        "the preset's",
        NOTES,
    )
    b.add_argument(
        "--learning-starts",
        type=step_count,
        metavar="N",
        help="random steps before learning (default: the preset's; paper: each algorithm's own, "
        f"{_warmups()}; quick {PRESETS['quick']['learning_starts']:,}; with --steps alone, at "
        "most a fifth of the budget)",
    )
    # the final evaluation's protocol fields, their help Protocol's own (rrls evaluate's too)
    add_protocol_options(b, ("mesh", "episodes"), "the preset's", "final evaluation: ")
    b.add_argument(
        "--protocol",
        metavar="FILE",
        help="the evaluation protocol, a JSON file as Protocol.to_json writes it (set, mesh, "
        "episodes, seed, physics, split, disruptors, schedule, max_episode_steps, ...; fields "
        "left out take Protocol's defaults): it replaces the preset's protocol whole, and "
        "--uncertainty, --mesh, --episodes, --physics, --split, --rate-limit, --recheck "
        "override it. Its max_episode_steps truncates the training's episodes too",
    )
    add_protocol_options(b, ("recheck",), "the preset's")
    b.add_argument(
        "--workers",
        type=worker_count,
        metavar="N",
        help="N worker processes training and evaluating runs in parallel, at most 1024; each "
        "run needs a process of its own, so 0 (elsewhere: none, the work runs in this process) "
        "is refused here (default: the machine's cores; Ray: the cluster; results do not "
        "depend on it)",
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
        "the runs of a process share its one thread; with --simulator warp a task's algorithms "
        "share the process and each twin step. Default: every seed of a cell with "
        "--device cuda, 1 on cpu",
    )
    b.add_argument(
        "--yes",
        action="store_true",
        help=f"start without asking: from a terminal, more than {CONFIRM_ABOVE} runs to start "
        "ask for confirmation first (never asked without a terminal, or with CI set)",
    )
    return b


def run(args: argparse.Namespace) -> int:
    """Run (or, with --dry-run, plan) the benchmark; a bad spec is one line, exit status 2."""
    return guarded(args, _benchmark)


def _benchmark(args: argparse.Namespace) -> int:
    spec, jobs = spec_from(args)
    if args.backend == "ray":
        try:
            import ray  # noqa: F401
        except ImportError:
            return fail("benchmark", f"--backend ray needs Ray: {install_hint('ray')}")
    try:
        import torch  # noqa: F401
    except ImportError:
        return fail("benchmark", f"training needs torch: {install_hint('train')}")
    from pathlib import Path

    from rrls.agents import algorithm

    for name in spec.algos:  # a plug-in that is no learner: one line now, not in a worker
        if name not in BUILT_IN:
            try:
                algorithm(name)
            except ValueError as err:
                return fail("benchmark", str(err))

    out = Path(args.out)
    if out.exists() and not out.is_dir():  # the real run refuses it: so does the dry run
        return fail("benchmark", f"--out {out} is a file, not a directory: choose another --out")
    if args.dry_run:
        return _dry_run(out, spec, jobs or 0, args.backend, args.pack)
    from rrls.benchmark.runner import benchmark, kept_runs
    from rrls.interrupts import keeping
    from rrls.report import make_report

    with keeping(lambda: kept_runs(out, spec)):
        todo, _ = pending(out, spec)
        if not confirmed("benchmark", len(todo), args.yes):
            return 1
        code = benchmark(
            out, spec, jobs or 0, args.backend, args.ray_address, report=make_report, pack=args.pack
        )
        if (out / "report" / "summary.json").exists():
            print(results_table(out))
    return code


def _dry_run(root: Any, spec: Any, jobs: int, backend: str, pack: int | None) -> int:
    """What ``rrls benchmark`` would do in ``root``, without doing any of it."""
    from rrls.benchmark.benchfile import reconcile
    from rrls.benchmark.pipeline import default_pack, groups
    from rrls.benchmark.runner import plan

    spec, (todo, finished) = reconcile(root, spec), pending(root, spec)
    pack = default_pack(spec, pack)
    print(plan(root, spec, len(todo), finished, jobs, backend, pack, todo))
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


__all__ = ["NAME", "add_parser", "run"]
