"""``rrls submit``: evaluate a policy trained elsewhere under a benchmark's protocol and store it
as an algorithm's run (the library's :func:`rrls.submissions.steps.submit`). A command of
its own: it needs neither SciPy nor torch."""

from __future__ import annotations

import argparse
import shlex

from rrls.argtypes import seed_value, step_count, worker_count, workers_help
from rrls.benchmark.grid import PRESETS
from rrls.cli.parsing import fail

NAME = "submit"


def add_parser(sub: argparse._SubParsersAction) -> argparse.ArgumentParser:
    """Register ``rrls submit`` on the ``rrls`` sub-command parser."""
    s = sub.add_parser(
        NAME,
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
    s.add_argument(
        "--task",
        required=True,
        metavar="TASK",
        help="one of the benchmark's tasks (another one only with --add-task)",
    )
    s.add_argument(
        "--seed",
        required=True,
        type=seed_value,
        metavar="S",
        help="the training seed the policy was trained with: its label in the report (the "
        "episodes' seeds are the benchmark's)",
    )
    s.add_argument(
        "--steps",
        type=step_count,
        metavar="N",
        help="the training budget you declare (env steps: 30000, 1e4, 100k; default: what the "
        "policy records, else not stated); the report prints it beside the benchmark's",
    )
    s.add_argument(
        "--budget",
        action="append",
        metavar="KEY=VALUE",
        help="anything else about the training budget (e.g. 'gpu hours=3'); repeatable",
    )
    s.add_argument(
        "--add-task",
        action="store_true",
        help="a submissions-only benchmark: add --task to its tasks on purpose (a benchmark "
        "with baselines never grows here: `rrls benchmark --tasks` trains them)",
    )

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
        type=worker_count,
        metavar="N",
        help=workers_help("the machine's cores", "playing the evaluation's episodes"),
    )
    return s


def run(args: argparse.Namespace) -> int:
    """Evaluate and store the submission, then say what to run next."""
    from rrls.evaluation import PolicyError
    from rrls.submissions.steps import SubmitError, submit

    if args.workers is not None and args.workers < 0:
        return fail("submit", f"--workers must be >= 0 (0: in this process), got {args.workers}")
    budget = {}
    for item in args.budget or []:
        key, sep, value = item.partition("=")
        if not sep or not key.strip():
            return fail("submit", f"--budget {item!r}: write KEY=VALUE (e.g. 'gpu hours=3')")
        if key.strip() in budget:
            return fail("submit", f"--budget {key.strip()!r} is given twice; give each key once")
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
            progress=True,  # a bar on a terminal, plain lines in a log (as evaluate)
            add_task=args.add_task,
            steps=args.steps,
            budget=budget,
        )
    except (SubmitError, PolicyError) as err:
        return fail("submit", str(err))
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


__all__ = ["NAME", "add_parser", "run"]
