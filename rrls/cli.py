"""The ``rrls`` command line. Thin: it parses arguments and calls the library."""

from __future__ import annotations

import argparse
import sys


def build_parser() -> argparse.ArgumentParser:
    from rrls import __version__

    parser = argparse.ArgumentParser(prog="rrls", description="Robust Reinforcement Learning Suite")
    parser.add_argument("--version", action="version", version=f"rrls {__version__}")
    sub = parser.add_subparsers(dest="command", required=True)

    check = sub.add_parser(
        "check",
        help="build every env and run short random episodes at the nominal point and set corners",
    )
    check.add_argument("--task", action="append", help="only these tasks (repeatable)")
    check.add_argument("--steps", type=int, default=100, help="steps per episode (default 100)")
    check.add_argument("--seed", type=int, default=0)

    ev = sub.add_parser(
        "evaluate",
        help="evaluate a policy over a mesh of an uncertainty set (worst / average case)",
        description="Evaluate POLICY over a uniform mesh of the uncertainty set (paper §4). "
        "Re-running the same command with the same --out resumes an interrupted evaluation.",
    )
    ev.add_argument("policy", help="a policy file (.npz MLP) or an `rrls train` run directory")
    ev.add_argument(
        "--task",
        help="ant, halfcheetah, hopper, humanoidstandup, "
        "invertedpendulum or walker (default: the policy's own task, if it records one)",
    )
    ev.add_argument("--uncertainty", default="3d", help="1d, 2d, 3d, rarl or nominal (default 3d)")
    ev.add_argument("--mesh", type=int, default=10, help="points per dimension (default 10)")
    ev.add_argument("--episodes", type=int, default=5, help="episodes per point (default 5)")
    ev.add_argument("--seed", type=int, default=0)
    ev.add_argument("--workers", type=int, default=None, help="processes (default: all cores)")
    ev.add_argument(
        "--batch-size",
        type=int,
        default=None,
        help="live episodes per worker (results do not depend on it)",
    )
    ev.add_argument(
        "--no-endpoint",
        action="store_true",
        help="the original code's np.arange mesh (upper bounds excluded)",
    )
    ev.add_argument(
        "--out",
        help="output directory (default: evaluations/<task>-<uncertainty>-mesh<M>-ep<E>-seed<S>)",
    )
    ev.add_argument("--plot", action="store_true", help="also write DIR/returns.png")

    tr = sub.add_parser(
        "train",
        help="train a baseline (td3, dr, rarl, nrmdp, m2td3); needs the `train` extra",
        description="Train a baseline with the paper's hyper-parameters. Checkpoints are written "
        "to --out; --resume continues a killed run exactly where it stopped.",
    )
    tr.add_argument("--algo", required=True, choices=["td3", "dr", "rarl", "nrmdp", "m2td3"])
    tr.add_argument(
        "--task",
        required=True,
        choices=["ant", "halfcheetah", "hopper", "humanoidstandup", "invertedpendulum", "walker"],
    )
    tr.add_argument(
        "--uncertainty",
        choices=["1d", "2d", "3d", "rarl"],
        default=None,
        help="default: rarl for RARL, else 3d (2d for invertedpendulum)",
    )
    tr.add_argument("--steps", type=int, default=5_000_000, help="env steps (default 5M)")
    tr.add_argument(
        "--learning-starts",
        type=int,
        default=25_000,
        help="random-action steps before learning (default 25k)",
    )
    tr.add_argument(
        "--eval-every",
        type=int,
        default=50_000,
        help="evaluate every N steps (0 disables; default 50k)",
    )
    tr.add_argument("--seed", type=int, default=0)
    tr.add_argument(
        "--out",
        default=None,
        help="run directory (default runs/<algo>-<task>-<uncertainty>-seed<S>)",
    )
    tr.add_argument("--device", default="cpu", help="cpu or cuda")
    tr.add_argument("--resume", action="store_true", help="continue the run in --out")
    tr.add_argument(
        "--hidden",
        type=int,
        nargs="+",
        default=[256, 256],
        help="hidden layer sizes (default 256 256)",
    )
    tr.add_argument(
        "--batch-size", type=int, default=None, help="default: the paper's (TD3 256, M2TD3 100)"
    )
    tr.add_argument(
        "--learning-rate",
        type=float,
        default=None,
        help="Adam step size of actor and critics (default: the paper's 3e-4)",
    )
    tr.add_argument(
        "--normalize-omega",
        action="store_true",
        help="M2TD3: critics see the parameters rescaled to [-1, 1] (the authors feed raw values)",
    )
    tr.add_argument(
        "--eval-mesh",
        type=int,
        default=0,
        help="also evaluate over a mesh with N points per dimension (default 0: off)",
    )
    tr.add_argument("--eval-episodes", type=int, default=5)
    tr.add_argument(
        "--checkpoint-every",
        type=int,
        default=50_000,
        help="checkpoint at the first episode end after every N steps",
    )
    tr.add_argument("--stop-at", type=int, default=None, help=argparse.SUPPRESS)

    quick = sub.add_parser(
        "quickstart",
        help="the `quick` benchmark preset: five algorithms on InvertedPendulum's 1D set, "
        "evaluated, reported, plotted (~10 min on 2 cores)",
    )
    quick.add_argument("--out", default="quickstart", help="output directory")
    quick.add_argument("--steps", type=int, default=None, help="steps per algorithm")
    quick.add_argument("--seed", type=int, default=0)

    from rrls.experiments.cli import add_parsers

    add_parsers(sub)  # benchmark, report

    plot = sub.add_parser("plot", help="plot a saved evaluation: return over the uncertainty set")
    plot.add_argument("dir", help="an `rrls evaluate` output directory")
    plot.add_argument("--out", help="PNG path (default DIR/returns.png)")
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    if args.command == "check":
        from rrls.check import main as check_main

        return check_main(args.task, args.steps, args.seed)
    if args.command == "evaluate":
        return _evaluate(args)
    if args.command == "train":
        return _train(args)
    if args.command in ("benchmark", "report", "quickstart"):
        from rrls.experiments.cli import run

        return run(args)
    if args.command == "plot":
        from rrls.evaluation.plots import plot_result

        print(plot_result(args.dir, args.out))
        return 0
    raise AssertionError(args.command)  # argparse rejects unknown commands


def _evaluate(args: argparse.Namespace) -> int:
    from pathlib import Path

    from rrls.evaluation import evaluate, load_policy

    policy = load_policy(args.policy)
    task = args.task or getattr(policy, "metadata", {}).get("task")
    if task is None:
        raise SystemExit("rrls evaluate: --task is required (the policy does not record its task)")
    out = Path(
        args.out
        or f"evaluations/{task}-{args.uncertainty}-mesh{args.mesh}"
        f"-ep{args.episodes}-seed{args.seed}"
    )
    result = evaluate(
        policy,
        task,
        args.uncertainty,
        nb_mesh_dim=args.mesh,
        episodes=args.episodes,
        seed=args.seed,
        workers=args.workers,
        endpoint=not args.no_endpoint,
        out_dir=out,
        batch_size=args.batch_size,
        progress=True,
    )
    summary = result.summary()
    worst = ", ".join(f"{k}={v:.4g}" for k, v in result.worst_point.items()) or "nominal model"
    rows = [
        ("task / set", f"{result.task} / {args.uncertainty}"),
        (
            "mesh",
            f"{len(result.per_point)} points ({args.mesh} per dimension) "
            f"x {args.episodes} episodes, seed {args.seed}",
        ),
        ("worst case", f"{result.worst_case:,.2f}   at {worst}"),
        ("average case", f"{result.average_case:,.2f}"),
        ("diverged", f"{summary['diverged']} of {summary['episodes_total']} episodes"),
        ("written", f"{out / 'summary.json'}, {out / _table_file(out)}"),
    ]
    if args.plot:
        from rrls.evaluation.plots import plot_result

        rows.append(("plot", str(plot_result(out))))
    width = max(len(k) for k, _ in rows)
    for key, value in rows:
        print(f"{key:<{width}}  {value}")
    return 0


def _train(args: argparse.Namespace) -> int:
    try:
        from rrls.agents import Interrupted, TrainConfig, default_uncertainty, train
    except ImportError as err:
        raise SystemExit(f"rrls train needs torch: pip install 'rrls[train]' ({err})") from err
    uncertainty = args.uncertainty or default_uncertainty(args.algo, args.task)
    out = args.out or f"runs/{args.algo}-{args.task}-{uncertainty}-seed{args.seed}"
    config = TrainConfig(
        algo=args.algo,
        task=args.task,
        uncertainty=uncertainty,
        steps=args.steps,
        learning_starts=args.learning_starts,
        eval_every=args.eval_every,
        seed=args.seed,
        out=out,
        device=args.device,
        hidden=tuple(args.hidden),
        batch_size=args.batch_size,
        learning_rate=args.learning_rate,
        normalize_omega=args.normalize_omega,
        eval_mesh=args.eval_mesh,
        eval_episodes=args.eval_episodes,
        checkpoint_every=args.checkpoint_every,
        stop_at=args.stop_at,
    )
    try:
        run_dir = train(config, resume=args.resume)
    except Interrupted as stop:
        print(f"{stop}; continue with --resume")
        return 3
    except FileExistsError as err:
        raise SystemExit(f"rrls train: {err}") from err
    print(
        f"trained {args.algo} on {args.task}/{uncertainty}: {run_dir}/policy.npz "
        f"(evaluate with: rrls evaluate {run_dir})"
    )
    return 0


def _table_file(out: object) -> str:
    from pathlib import Path

    return "episodes.parquet" if (Path(str(out)) / "episodes.parquet").exists() else "episodes.csv"


if __name__ == "__main__":
    sys.exit(main())
