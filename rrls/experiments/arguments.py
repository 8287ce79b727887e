"""The options of ``rrls benchmark``, ``rrls report`` and ``rrls submit`` (what they do:
:mod:`rrls.experiments.commands`). Ranges are checked by the spec, so that errors are one line with
exit status 2."""

from __future__ import annotations

import argparse

from rrls.argtypes import seed_value, step_count, worker_count
from rrls.deprecation import DeprecatedOption
from rrls.experiments.reference import SHIPPED
from rrls.experiments.spec import ALGOS, BUILT_IN, PAPER_TASKS, PRESETS
from rrls.physics import SIMULATORS
from rrls.seeds import EXAMPLES

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
        "hopper (~9.5 CPU-hours: the early-training locomotion reference), halfcheetah (~22 "
        "CPU-hours: the locomotion reference where the agents have learned), paper (the "
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
        "--uncertainty",
        metavar="SET",
        help="evaluation set (and DR/M2TD3's training set): 1d, 2d, 3d (default: the preset's)",
    )
    b.add_argument(
        "--seeds",
        metavar="SEEDS",
        help=f"the seeds, a list or range: {EXAMPLES} (default: the preset's). A bare N, once "
        "a count of seeds here, is refused: write 0-2 for three seeds, 3-3 for seed 3",
    )
    b.add_argument(
        "--physics",
        choices=["v5", "paper"],
        help="v5 (default: Gymnasium v5, rrls's parameter semantics) or paper (the paper's "
        "Gymnasium v5 envs, the original code's parameter writes, np.arange mesh) for training and "
        "evaluation; recorded as given in benchmark.json",
    )
    b.add_argument(
        "--simulator",
        choices=list(SIMULATORS),
        help="what steps the training envs: mujoco (default: CPU MuJoCo) or warp (each task's "
        "MuJoCo Warp twin on --device, the warp extra); evaluations stay on CPU MuJoCo",
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
        "--steps",
        type=step_count,
        metavar="N",
        help="training steps per run: 30000, 1e4, 100k (default: the preset's)",
    )
    b.add_argument(
        "--learning-starts",
        type=step_count,
        metavar="N",
        help="random steps before learning (default: the preset's; paper: each algorithm's own, "
        "25 000, M2TD3 100 000; quick 1 000; "
        "with --steps alone, at most a fifth of the budget)",
    )
    b.add_argument(
        "--eval-every",
        type=step_count,
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
        type=worker_count,
        metavar="N",
        help="worker processes: runs in parallel, >= 1 (each run has its own process: 0, 'in "
        "this process' elsewhere, does not apply; default: the number of cores; Ray: the "
        "cluster)",
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
        help=f"reference results (.json/.csv, or a shipped name: {', '.join(SHIPPED)}) normalising"
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
    r.add_argument(
        "--rename",
        action="append",
        metavar="NAME=TEXT",
        help="show algorithm NAME's row as TEXT in every table and figure (NAME@REF: the "
        "reference REF's row, e.g. td3@quick='TD3, rrls quick'); repeatable",
    )

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
    s.add_argument(
        "--task",
        required=True,
        metavar="TASK",
        help="one of the benchmark's tasks (another one only with --add-task)",
    )
    s.add_argument("--seed", required=True, type=seed_value, metavar="S", help="the policy's seed")
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
        help="worker processes: the evaluation's; 0: in this process (default: the number of "
        "cores)",
    )
    add_withdraw(sub)


def add_withdraw(sub: argparse._SubParsersAction) -> None:
    """``rrls withdraw``: take submissions out of a benchmark."""
    w = sub.add_parser(
        "withdraw",
        help="take an algorithm's submissions out of a benchmark (undoes `rrls submit`)",
        description="Remove the submitted runs of --algo (all, or those of --task / --seed) "
        "from BENCH_DIR; a task left without runs leaves a submissions-only benchmark's task "
        "list, so later reports stay complete. The benchmark's own runs are never removed.",
    )
    w.add_argument("bench_dir", metavar="BENCH_DIR", help="a benchmark directory")
    w.add_argument("--algo", required=True, metavar="NAME", help="the submitted algorithm")
    w.add_argument("--task", metavar="TASK", help="only its runs on this task")
    w.add_argument("--seed", type=seed_value, metavar="S", help="only its runs of this seed")


__all__ = ["CONFIRM_ABOVE", "add_parsers", "add_withdraw"]
