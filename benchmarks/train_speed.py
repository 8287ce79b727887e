"""Training speed: rrls' TD3 and SAC against CleanRL's, side by side.

One run, this machine, Hopper (nominal), the paper's sizes (256-256, batch 256), one update per
env step after learning starts. Env steps per second of:

(a) CleanRL's TD3 loop: ``td3_continuous_action.py`` as published, step for step
    (``cleanrl_loops.cleanrl``: its vector env, its replay buffer, which is
    Stable-Baselines3's, its TensorBoard logging). Needs ``stable-baselines3`` (``pip install
    -e .[bench]``); the CleanRL rows are skipped without it;
(a') the same update in a lean loop (``cleanrl_loops.straightforward``): two separate critic
    modules, a Python loop over parameters for Polyak averaging, plain Adam, numpy<->torch
    conversion of every transition and batch, no vector env, a list replay;
(a'') (a') with denormals flushed to zero, to separate that one setting (which ``rrls train``
    makes) from the rest of the work;
(a-SAC) CleanRL's SAC loop: ``sac_continuous_action.py`` as published
    (``cleanrl_loops.cleanrl_sac``), the reference of the SAC rows;
(b) ``rrls.agents`` TD3 (plain PyTorch: batched modules, both critics in one ``baddbmm`` per
    layer, autograd, ``torch.optim.Adam``; tensor replay, acting in numpy);
(b') (b) with ``--compile`` (the whole update through ``torch.compile``; compiled before the
    timed window, the compile cache in ``TORCHINDUCTOR_CACHE_DIR``);
(c) M2TD3 (``rrls.agents.algos.m2td3``), (d) SAC (``rrls.agents.algos.sac``), (d') SAC with
    ``--compile``. ``--rows`` picks rows (default: all).

Every measurement runs in a fresh process. Ratios are against CleanRL's loop of the same
algorithm (TD3's for every row but SAC's), against (a) and against (a').

Then runs sharing the machine (``--no-shared`` skips it): one run alone with one thread and with
the default (adaptive) threads, as many runs at once as there are cores with the default, and
the same with every run on all cores (oversubscribed, the collapse the default avoids). Target
(issue 11): the shared default >= 0.9 x cores x one single-threaded run.

Target: (b) >= 2x the straightforward version. Measured after learning starts and ``--warmup``
updates (default 3 000: enough for dead units' Adam moments to reach the denormal range, as in
real training).

Then groups of runs (``--groups``: this section alone; ``--no-groups`` skips it; the
measurement lives in ``benchmarks/group_speed.py``): for each ``--ks`` K, ``--algos`` and
``--device``, (a) CleanRL's loop, (b) K runs in one process, (c) K separate processes.

    python benchmarks/train_speed.py [--task hopper] [--steps 600] [--warmup 3000] [--rounds 3]
                                     [--wall] [--no-shared] [--groups | --no-groups]
                                     [--ks 1 8 32] [--algos td3 m2td3] [--device cpu cuda]
                                     [--group-steps 300] [--group-warmup 1000]
                                     [--process-steps 100] [--learning-starts 1000]
"""

from __future__ import annotations

import argparse
import importlib.util
import multiprocessing
import os
import statistics
import tempfile
import time
import warnings
from pathlib import Path

import gymnasium as gym
import torch
from cleanrl_loops import cleanrl, cleanrl_sac, straightforward
from group_speed import groups, timed_config

from rrls.agents import train


# -- (b), (c) rrls ---------------------------------------------------------------------------------
def rrls_algo(
    algo: str,
    task: str,
    steps: int,
    warmup: int,
    threads: int | None = None,
    compile: bool = False,  # rrls train's option
) -> float:
    """Env steps/s of ``rrls.agents`` after learning starts, timed at the env's ``step`` calls
    (``threads``: ``rrls train --threads``; None is its default, the adaptive count;
    ``compile``: ``--compile``, paid before the window: the first updates compile)."""
    import importlib

    module = importlib.import_module(f"rrls.agents.algos.{algo}")
    learning_starts = 1000
    stamps: list[float] = []

    class Clock(gym.Wrapper):
        def step(self, action):
            stamps.append(time.perf_counter())
            return self.env.step(action)

    plain = module.make_env
    module.make_env = lambda *a, **k: Clock(plain(*a, **k))
    try:
        with tempfile.TemporaryDirectory() as out:
            steps_in_all = learning_starts + warmup + steps + 1
            train(timed_config(algo, task, steps_in_all, out, learning_starts, threads, compile))
    finally:
        module.make_env = plain
    first = learning_starts + warmup
    return steps / (stamps[first + steps] - stamps[first])


def _rrls_td3(task: str, steps: int, warmup: int, threads: int | None) -> float:
    warnings.simplefilter("ignore")
    return rrls_algo("td3", task, steps, warmup, threads)


def side_by_side(runs: int, threads: int | None, task: str, steps: int, warmup: int) -> float:
    """Summed env steps/s of ``runs`` TD3 runs started together, each in its own process."""
    ctx = multiprocessing.get_context("spawn")
    with ctx.Pool(runs) as pool:
        return sum(pool.starmap(_rrls_td3, [(task, steps, warmup, threads)] * runs))


def _measure(name: str, task: str, steps: int, warmup: int) -> float:
    warnings.simplefilter("ignore")
    if name == "cleanrl":
        return cleanrl(task, steps, warmup)
    if name == "cleanrl-sac":
        return cleanrl_sac(task, steps, warmup)
    if name in ("straightforward", "ftz"):
        if name == "ftz":
            torch.set_flush_denormal(True)
        return straightforward(task, steps, warmup)
    algo, _, compiled = name.partition("+")
    return rrls_algo(algo, task, steps, warmup, compile=bool(compiled))


def wall_times(
    task: str,
    steps: int = 22_000,
    random_steps: int = 1_000,
    rounds: int = 1,
    against: str | None = None,
) -> dict[str, list[float]]:
    """Wall seconds of ``steps`` env steps (``random_steps`` random, then one update per step),
    start-up included, each a fresh process, ``rounds`` times in turn: CleanRL's loop (row (a))
    and ``rrls train`` with its defaults (floor: rrls >= 1.3x) and with ``--compile`` (compile
    time included). ``against``: a checkout of
    another rrls (e.g. ``git worktree add ../old <commit>``) whose ``rrls train`` is timed in
    the same rounds, so a change of core is compared on one machine in one session."""
    import subprocess
    import sys

    here, updates = str(Path(__file__).parent), steps - random_steps
    cleanrl_cmd = (
        f"import sys, warnings; warnings.simplefilter('ignore'); sys.path.insert(0, {here!r});"
        f"import cleanrl_loops; cleanrl_loops.cleanrl({task!r}, {updates}, 0)"
    )
    times: dict[str, list[float]] = {}
    with tempfile.TemporaryDirectory() as out:
        rrls_cmd = [
            *(sys.executable, "-m", "rrls", "train", "--algo", "td3", "--task", task),
            *("--steps", str(steps), "--learning-starts", str(random_steps)),
            *("--eval-every", "0", "--out", out, "--overwrite"),
        ]
        cmds = {"cleanrl": ([sys.executable, "-c", cleanrl_cmd], None), "rrls": (rrls_cmd, None)}
        cmds["compiled"] = ([*rrls_cmd, "--compile"], None)  # the default on a CPU: eager
        if against:  # its own package first on the path, in a clean working directory
            env = {**os.environ, "PYTHONPATH": str(Path(against).resolve())}
            cmds["against"] = (rrls_cmd, env)
        for _ in range(rounds):
            for name, (cmd, env) in cmds.items():
                start = time.perf_counter()
                subprocess.run(cmd, check=True, capture_output=True, env=env, cwd=out)
                times.setdefault(name, []).append(time.perf_counter() - start)
    return times


ROWS = {
    "cleanrl": "(a) CleanRL's loop as published (SB3 replay, vector env)",
    "straightforward": "(a') the same update, lean loop",
    "ftz": "(a'') (a') + flush denormals to zero",
    "td3": "(b) rrls TD3",
    "td3+compile": "(b') rrls TD3, --compile",
    "m2td3": "(c) rrls M2TD3 (batch 100, 5 candidates)",
    "cleanrl-sac": "(a-SAC) CleanRL's SAC loop as published (SB3 replay, vector env)",
    "sac": "(d) rrls SAC (CleanRL's sac_continuous_action hyper-parameters)",
    "sac+compile": "(d') rrls SAC, --compile",
}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--task", default="hopper")
    parser.add_argument("--steps", type=int, default=600)
    parser.add_argument("--warmup", type=int, default=3000)
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument(
        "--rows", nargs="+", default=list(ROWS), choices=list(ROWS), help="the rows to time"
    )
    parser.add_argument(
        "--wall",
        action="store_true",
        help="also time 22 000 steps end to end, CleanRL's loop vs rrls train (~5 min a round)",
    )
    parser.add_argument("--wall-rounds", type=int, default=1, help="rounds of --wall (median)")
    parser.add_argument(
        "--wall-against",
        metavar="CHECKOUT",
        help="with --wall: also time another rrls checkout's `rrls train` in the same rounds",
    )
    parser.add_argument(
        "--no-shared",
        dest="shared",
        action="store_false",
        help="skip the runs-sharing-the-machine table (threads)",
    )
    section = parser.add_mutually_exclusive_group()
    section.add_argument(
        "--groups",
        dest="only_groups",
        action="store_true",
        help="only the groups-of-runs table (K runs in one process vs K processes)",
    )
    section.add_argument(
        "--no-groups", dest="groups", action="store_false", help="skip the groups-of-runs table"
    )
    parser.add_argument("--ks", type=int, nargs="+", default=[1, 8, 32], metavar="K")
    parser.add_argument("--algos", nargs="+", default=["td3"], choices=["td3", "m2td3"])
    parser.add_argument(
        "--device",
        nargs="+",
        default=["cpu"],
        choices=["cpu", "cuda"],
        help="devices of the groups table (cuda rows are skipped without a GPU)",
    )
    parser.add_argument("--group-steps", type=int, default=300, help="(b)'s timed loop steps")
    parser.add_argument(
        "--group-warmup", type=int, default=1000, help="updates before the window, (b) and (c)"
    )
    parser.add_argument(
        "--process-steps", type=int, default=100, help="(c)'s timed steps per process"
    )
    parser.add_argument("--learning-starts", type=int, default=1000, help="random steps first")
    parser.add_argument("--group-rounds", type=int, default=1)
    args = parser.parse_args()
    warnings.simplefilter("ignore")
    if args.only_groups:
        groups(args)
        return
    names = [name for name in ROWS if name in args.rows]
    if importlib.util.find_spec("stable_baselines3") is None:
        print("stable-baselines3 is not installed: row (a) skipped (pip install -e .[bench])")
        names = [name for name in names if not name.startswith("cleanrl")]
    runs: dict[str, list[float]] = {k: [] for k in names}
    # each measurement in a fresh process: flush-to-zero is per thread and inherited, so one
    # implementation's setting must not leak into the next
    ctx = multiprocessing.get_context("spawn")
    with ctx.Pool(1, maxtasksperchild=1) as pool:
        for _ in range(args.rounds):
            for name in runs:
                job = (name, args.task, args.steps, args.warmup)
                runs[name].append(pool.apply(_measure, job))
    shared: dict[str, list[float]] = {}
    if args.shared:
        cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else 2
        cases = {
            "alone-1": (1, 1),
            "alone-default": (1, None),
            "shared-default": (cores, None),
            "shared-all": (cores, cores),
        }
        shared = {k: [] for k in cases}
        for _ in range(args.rounds):
            for key, (n, threads) in cases.items():
                shared[key].append(side_by_side(n, threads, args.task, args.steps, args.warmup))
    med = {k: statistics.median(v) for k, v in runs.items()}
    print(
        f"\n{args.task}, CPU ({torch.get_num_threads()} threads), 256-256, one update per env "
        f"step, median of {args.rounds} rounds x {args.steps} steps\n"
    )
    refs = [k for k in ("cleanrl", "straightforward") if k in med]
    print(
        "| implementation | steps/s | ratio vs CleanRL, same algorithm |"
        + "".join(f" ratio vs {k} |" for k in refs)
    )
    print("|---|---|---|" + "---|" * len(refs))
    for name, value in med.items():
        own = "cleanrl-sac" if name.startswith("sac") else "cleanrl"
        mine = own in med and not name.startswith("cleanrl")
        same = f" {value / med[own]:.2f}x |" if mine else " |"
        ratios = "".join(f" {value / med[k]:.2f}x |" for k in refs)
        print(f"| {ROWS[name]} | {value:.0f} |{same}{ratios}")
    if args.wall and "cleanrl" in med:
        wall = {
            k: statistics.median(v)
            for k, v in wall_times(
                args.task, rounds=args.wall_rounds, against=args.wall_against
            ).items()
        }
        print(
            f"\nWall time, 22 000 steps (1 000 random), start-up included, median of "
            f"{args.wall_rounds}: CleanRL's loop {wall['cleanrl']:.1f} s, rrls train (defaults) "
            f"{wall['rrls']:.1f} s: {wall['cleanrl'] / wall['rrls']:.2f}x (floor >= 1.3x); "
            f"--compile {wall['compiled']:.1f} s: {wall['cleanrl'] / wall['compiled']:.2f}x"
        )
        if "against" in wall:
            print(
                f"  {args.wall_against}: rrls train {wall['against']:.1f} s: "
                f"{wall['cleanrl'] / wall['against']:.2f}x; this checkout vs it "
                f"{wall['against'] / wall['rrls']:.2f}x"
            )
    if shared:
        print_shared(shared, med, cores, args.rounds)
    if args.groups:
        groups(args)


def print_shared(
    shared: dict[str, list[float]], med: dict[str, float], cores: int, rounds: int
) -> None:
    """The runs-sharing-the-machine table."""
    sm = {k: statistics.median(v) for k, v in shared.items()}
    one = sm["alone-1"]
    print(
        f"\nRuns sharing the machine ({cores} cores; TD3, summed env steps/s, median of "
        f"{rounds}). Target: {cores} runs at once with the default threads >= 0.9 x "
        f"{cores} x one single-threaded run; one run alone with the default >= 1.5x (a).\n"
    )
    print(
        "| runs at once | threads per run | env steps/s (sum) | vs one 1-thread run |"
        + (" ratio vs (a) |" if "cleanrl" in med else "")
    )
    print("|---|---|---|---|" + ("---|" if "cleanrl" in med else ""))
    labels = {
        "alone-1": ("1", "1 (--threads 1)"),
        "alone-default": ("1", "default (adaptive)"),
        "shared-default": (str(cores), "default (adaptive)"),
        "shared-all": (str(cores), f"{cores} (--threads {cores}: oversubscribed)"),
    }
    for key, value in sm.items():
        runs_at_once, threads = labels[key]
        extra = f" {value / med['cleanrl']:.2f}x |" if "cleanrl" in med else ""
        print(f"| {runs_at_once} | {threads} | {value:.0f} | {value / one:.2f}x |{extra}")


if __name__ == "__main__":
    main()
