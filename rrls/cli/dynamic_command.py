"""``rrls evaluate-dynamic``: a two-player run's protagonist against its own trained adversary
(paper Table 6; the library's :func:`rrls.evaluation.evaluate_run_dynamic`). Named
``dynamic_command`` because :mod:`rrls.evaluation.dynamic` is the engine behind it."""

from __future__ import annotations

import argparse

from rrls import argtypes
from rrls.argtypes import EPISODE_SEED_HELP, positive_int, seed_value, workers_help
from rrls.deprecation import DeprecatedOption
from rrls.evaluation.protocol import Protocol

NAME = "evaluate-dynamic"


def add_parser(sub: argparse._SubParsersAction) -> argparse.ArgumentParser:
    """Register ``rrls evaluate-dynamic`` on the ``rrls`` sub-command parser."""
    ed = sub.add_parser(
        NAME,
        help="a RARL / NR-MDP run's policy against its own trained adversary (paper Table 6)",
        description="Play a two-player run's final protagonist (policy.npz) against its own final "
        "adversary (adversary.npz) for --episodes episodes, in the game the run trained in "
        "(RARL's, TC-RMDP's rate-limited one, or NR-MDP's action mixing): the paper's Table 6.",
    )
    ed.add_argument("run_dir", help="an `rrls train` run directory holding adversary.npz")
    ed.add_argument(
        "--episodes",
        type=positive_int,
        default=Protocol.dynamic_episodes,  # the protocol's own default, the paper's
        metavar="N",
        help=f"episodes (default {Protocol.dynamic_episodes}, the paper's)",
    )
    ed.add_argument(
        "--episode-seed", type=seed_value, default=0, metavar="S", help=EPISODE_SEED_HELP
    )
    ed.add_argument(  # --seed names a training seed in every other command
        "--seed", dest="episode_seed", type=seed_value, action=DeprecatedOption,
        new="--episode-seed",
    )  # fmt: skip
    ed.add_argument(
        "--workers",
        type=argtypes.worker_count,
        default=None,
        metavar="N",
        help=workers_help("the machine's cores, at most one per episode", "playing the episodes"),
    )
    ed.add_argument(
        "--out",
        default=None,
        help="keep finished episodes in this directory; the same command again resumes",
    )
    return ed


def run(args: argparse.Namespace) -> int:
    """Play the episodes, then print the mean return and its spread."""
    from rrls.evaluation import evaldir, evaluate_run_dynamic
    from rrls.interrupts import keeping

    def kept() -> tuple[str, bool]:  # on Ctrl-C: the chunks on disk then, if any may be
        if args.out is None:
            return "nothing kept (without --out no episode is saved)", False
        return evaldir.kept(args.out, args.episodes, evaldir.DYNAMIC), True

    with keeping(kept):
        result = evaluate_run_dynamic(
            args.run_dir,
            episodes=args.episodes,
            seed=args.episode_seed,
            workers=args.workers,
            out_dir=args.out,
            progress=True,  # a bar on a terminal, plain lines in a log (as evaluate)
        )
        print(
            f"{result.env_id}: {result.mean:.2f} ± {result.std:.2f} over {args.episodes} episodes"
        )
    return 0


__all__ = ["NAME", "add_parser", "run"]
