"""``rrls evaluate``: a policy over a mesh of an uncertainty set, its worst and average case (the
library's :func:`rrls.evaluation.evaluate`). Its options, the default output directory and the
table it prints live here, so that the command reads in one place."""

from __future__ import annotations

import argparse
from typing import Any

from rrls import argtypes
from rrls.argtypes import (
    EPISODE_SEED_HELP,
    positive_int,
    seed_value,
    set_name,
    task_key,
    workers_help,
)
from rrls.cli.parsing import UsageError, task_keys
from rrls.cli.run_options import add_protocol_options
from rrls.deprecation import DeprecatedOption

NAME = "evaluate"


def add_parser(sub: argparse._SubParsersAction) -> argparse.ArgumentParser:
    """Register ``rrls evaluate`` on the ``rrls`` sub-command parser."""
    ev = sub.add_parser(
        NAME,
        help="evaluate a policy over a mesh of an uncertainty set (worst / average case)",
        description="Evaluate POLICY over a uniform mesh of the uncertainty set (paper §4). "
        "Re-running the same command with the same --out resumes an interrupted evaluation; "
        "a second evaluation into the same --out while one runs is refused.",
    )
    ev.add_argument(
        "policy",
        help="a policy file (.npz MLP), an `rrls train` run directory, a Stable-Baselines3 .zip "
        "or module:attribute (the last two run code from the file/module)",
    )
    ev.add_argument(
        "--task",
        type=task_key,
        metavar="TASK",
        help=f"one of {', '.join(task_keys())} (default: the policy's own task, if recorded)",
    )
    ev.add_argument(
        "--uncertainty",
        type=set_name,
        default=None,
        help="the set to mesh: 1d, 2d, 3d (masses/friction), rarl (forces) or nominal (the "
        "model as shipped). Default: the set the policy was trained on, else 3d (2d for "
        "invertedpendulum)",
    )
    # the protocol's fields, their help and defaults Protocol's own (rrls benchmark's too)
    add_protocol_options(ev, ("mesh", "episodes"), convert=positive_int)
    ev.add_argument(
        "--episode-seed", type=seed_value, default=0, metavar="S", help=EPISODE_SEED_HELP
    )
    ev.add_argument(  # --seed names a training seed in every other command
        "--seed", dest="episode_seed", type=seed_value, action=DeprecatedOption,
        new="--episode-seed",
    )  # fmt: skip
    ev.add_argument(
        "--workers",
        type=argtypes.worker_count,
        default=None,
        metavar="N",
        help=workers_help("the machine's cores", "playing the episodes"),
    )
    ev.add_argument(
        "--batch-size",
        type=positive_int,
        default=None,
        help="live episodes per worker (default: the engine's; results do not depend on it)",
    )
    ev.add_argument(
        "--no-endpoint",
        action="store_true",
        help="the original code's np.arange mesh (upper bounds excluded)",
    )
    ev.add_argument(
        "--physics",
        choices=["v5", "paper"],
        default=None,
        help="v5 (Gymnasium v5, rrls's parameter semantics) or paper (the paper's Gymnasium v5 "
        "envs, the original code's parameter writes, np.arange mesh); default: the physics the "
        "policy was trained on (rrls train records it), else v5",
    )
    ev.add_argument(
        "--split",
        metavar="KIND[:F]",
        default=None,
        help="also give in- and out-of-distribution worst/average case: extrapolation[:F] (ID: "
        "the centred box, a fraction F of each axis, default 0.5) or interpolation[:F] (ID: the "
        "set minus that box); default: the split the run trained under (rrls train --split)",
    )
    ev.add_argument(
        "--out",
        help="output directory (default: evaluations/<policy>-<task>-<uncertainty>-mesh<M>-ep<E>"
        "-seed<S>, S the --episode-seed)",
    )
    ev.add_argument("--plot", action="store_true", help="also write OUT/returns.png")
    return ev


def _split_rows(result: Any, split: str | None) -> list[tuple[str, str]]:
    """In- and out-of-distribution worst/average case, when the evaluation had a split."""
    scores = result.split_scores()
    if not scores:
        return []

    def fmt(v: float | None) -> str:
        return "-" if v is None else f"{v:,.2f}"

    return [
        (
            label,
            f"worst {fmt(scores[f'worst_case_{tag}'])}, average "
            f"{fmt(scores[f'average_case_{tag}'])} over {scores[f'points_{tag}']} points",
        )
        for tag, label in (("id", f"in distribution ({split})"), ("ood", "out of distribution"))
    ]


def run(args: argparse.Namespace) -> int:
    """Evaluate, then print the table of scores (and draw the plot with --plot)."""
    from pathlib import Path

    from rrls.evaluation import Protocol, evaldir, evaluate, load_policy
    from rrls.interrupts import NOTHING_YET, keeping
    from rrls.tasks import get_task

    policy = load_policy(args.policy)
    meta = getattr(policy, "metadata", {}) or {}
    task = args.task or meta.get("task")
    if task is None:
        raise UsageError("--task is required (the policy does not record its task)")
    task = get_task(task).key
    if meta.get("task") not in (None, task):
        raise UsageError(f"the policy was trained on {meta['task']!r}, not on --task {task!r}")
    protocol = Protocol.for_policy(
        meta,
        task,
        uncertainty=args.uncertainty,
        mesh=args.mesh,
        episodes=args.episodes,
        seed=args.episode_seed,
        physics=args.physics,
        endpoint=False if args.no_endpoint else None,
        split=args.split,
    )
    uncertainty, physics, split_text = protocol.uncertainty, protocol.physics, protocol.split
    out = Path(
        args.out
        or f"evaluations/{_policy_name(args.policy)}-{task}-{uncertainty}-mesh{args.mesh}"
        f"-ep{args.episodes}-seed{args.episode_seed}"
        + ("-paper" if physics == "paper" else "")
    )

    def kept() -> str:  # on Ctrl-C: the chunks on disk then
        try:
            rows = len(protocol.plan(task).points) * protocol.episodes
        except ValueError:  # a protocol refused before any episode ran
            return NOTHING_YET
        return evaldir.kept(out, rows)

    with keeping(kept):
        result = evaluate(
            policy,
            task,
            protocol=protocol,
            workers=args.workers,
            out_dir=out,
            batch_size=args.batch_size,
            progress=True,
        )
        _print(args, result, out, uncertainty, physics, split_text)
    return 0


def _print(
    args: argparse.Namespace, result: Any, out: Any, uncertainty: str, physics: str, split: Any
) -> None:
    """The table of scores (and the plot with --plot)."""
    summary = result.summary()
    worst = ", ".join(f"{k}={v:.4g}" for k, v in result.worst_point.items()) or "nominal model"
    rows = [
        ("task / set", f"{result.task} / {uncertainty} ({physics} physics)"),
        (
            "mesh",
            f"{len(result.per_point)} points ({args.mesh} per dimension) "
            f"x {args.episodes} episodes, episode seed {args.episode_seed}",
        ),
        ("worst case", f"{result.worst_case:,.2f}   at {worst}"),
        ("average case", f"{result.average_case:,.2f}"),
        *_split_rows(result, split),
        ("diverged", f"{summary['diverged']} of {summary['episodes_total']} episodes"),
        ("written", f"{out / 'summary.json'}, {out / _table_file(out)}"),
    ]
    width = max(len(k) for k, _ in rows)
    for key, value in rows:
        print(f"{key:<{width}}  {value}")
    if args.plot:  # after the table: a refused plot (nominal: one point) loses no result
        from rrls.evaluation.result_plot import plot_result

        print(f"{'plot':<{width}}  {plot_result(out)}")


def _policy_name(policy: str) -> str:
    """A folder-safe name for ``rrls evaluate``'s default output: a run directory's or file's
    name (``td3-hopper-3d-seed0``, ``agent``), or ``module.attr`` — so evaluating a second
    policy does not land in the first one's folder (refused there: another fingerprint)."""
    import re
    from pathlib import Path

    text = str(policy).rstrip("/")
    name = text.replace(":", ".") if ":" in text and not Path(text).exists() else Path(text).stem
    return re.sub(r"[^\w.-]+", "_", name)[:80] or "policy"


def _table_file(out: object) -> str:
    """The episode table's file name in OUT (Parquet when written as Parquet)."""
    from pathlib import Path

    return "episodes.parquet" if (Path(str(out)) / "episodes.parquet").exists() else "episodes.csv"


__all__ = ["NAME", "add_parser", "run"]
