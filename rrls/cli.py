"""The ``rrls`` command line. Thin: it parses arguments and calls the library."""

from __future__ import annotations

import argparse
import sys


def build_parser(with_train: bool = True) -> argparse.ArgumentParser:
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
    if with_train:  # the options come from the dataclasses, which need torch: only for `train`
        from rrls.agents.options import add_train_arguments

        add_train_arguments(tr)

    ed = sub.add_parser(
        "evaluate-dynamic",
        help="a RARL / NR-MDP run's policy against its own trained adversary (paper Table 6)",
    )
    ed.add_argument("run_dir", help="an `rrls train` run directory holding adversary.npz")
    ed.add_argument("--episodes", type=int, default=10, help="episodes (default 10, the paper's)")
    ed.add_argument("--seed", type=int, default=0, help="seed of the episodes' resets")

    quick = sub.add_parser(
        "quickstart",
        help="train TD3, M2TD3 and DR on InvertedPendulum's 1D set, evaluate, print, plot",
    )
    quick.add_argument("--out", default="quickstart", help="output directory")
    quick.add_argument("--steps", type=int, default=None, help="steps per algorithm")
    quick.add_argument("--seed", type=int, default=0)

    plot = sub.add_parser("plot", help="plot a saved evaluation: return over the uncertainty set")
    plot.add_argument("dir", help="an `rrls evaluate` output directory")
    plot.add_argument("--out", help="PNG path (default DIR/returns.png)")
    return parser


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    with_train = argv[:1] == ["train"]
    if with_train:
        try:
            import torch  # noqa: F401
        except ImportError as err:
            print(f"rrls train needs torch: pip install 'rrls[train]' ({err})", file=sys.stderr)
            return 2
    args = build_parser(with_train).parse_args(argv)
    if args.command == "check":
        from rrls.check import main as check_main

        return check_main(args.task, args.steps, args.seed)
    if args.command == "evaluate":
        return _evaluate(args)
    if args.command == "train":
        return _train(args)
    if args.command == "evaluate-dynamic":
        return _evaluate_dynamic(args)
    if args.command == "quickstart":
        from rrls.quickstart import main as quickstart_main

        return quickstart_main(args.out, args.steps, args.seed)
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
    from rrls.agents import Interrupted, train
    from rrls.agents.options import config_from_args

    try:
        config, resume = config_from_args(args)
        run_dir = train(config, resume=resume)
    except Interrupted as stop:
        print(f"{stop}; continue with --resume")
        return 3
    except (ValueError, FileExistsError) as err:
        print(f"rrls train: {err}", file=sys.stderr)
        return 2
    print(
        f"trained {config.algo} on {config.task}/{config.uncertainty}: {run_dir}/policy.npz "
        f"(evaluate with: rrls evaluate {run_dir})"
    )
    if (run_dir / "adversary.npz").exists():
        print(f"against its own adversary (paper Table 6): rrls evaluate-dynamic {run_dir}")
    return 0


def _evaluate_dynamic(args: argparse.Namespace) -> int:
    from rrls.evaluation import evaluate_run_dynamic

    try:
        if args.episodes < 1:
            raise ValueError(f"--episodes must be >= 1, got {args.episodes}")
        result = evaluate_run_dynamic(args.run_dir, episodes=args.episodes, seed=args.seed)
    except (ValueError, FileNotFoundError) as err:
        print(f"rrls evaluate-dynamic: {err}", file=sys.stderr)
        return 2
    print(f"{result.env_id}: {result.mean:.2f} ± {result.std:.2f} over {args.episodes} episodes")
    return 0


def _table_file(out: object) -> str:
    from pathlib import Path

    return "episodes.parquet" if (Path(str(out)) / "episodes.parquet").exists() else "episodes.csv"


if __name__ == "__main__":
    sys.exit(main())
