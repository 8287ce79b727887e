"""What a machine with a CUDA GPU runs first: the CUDA tests, the GPU speed table and the Hopper
reference at the largest budget that fits, in ~35 minutes, writing only small files to OUT_DIR.

    python3 benchmarks/gpu_runbook.py OUT_DIR                 # on the GPU machine
    python3 benchmarks/gpu_runbook.py OUT_DIR --device cpu --tiny   # the dry run (the test suite)

1. the CUDA tests (``tests/test_group.py -k "cuda or worker"``: CUDA graphs against the eager
   update, compiled too, and the env workers) -> ``tests.log``;
2. the GPU speed table (``benchmarks/train_speed.py --groups --ks 1 8 32 --algos td3 m2td3
   --device cuda``), against the targets of ``docs/protocol.md`` -> ``speed.md``;
3. the Warp twin (``--no-twin`` skips it; needs the ``warp`` extra): MuJoCo Warp's physics
   alone and the twin's whole step at 32 to 8 192 worlds, the per-task, per-kind check against
   CPU MuJoCo, K = 1, 32, 128 TD3 runs trained on it and a sim-to-sim check of one trained
   policy, and ``rrls train --simulator warp`` at K = 1, 32, 128 (TD3, M2TD3) against the CPU
   path -> ``warp_speed.log``, ``twin_speed.log``, ``twin_check/``, ``twin_train/``,
   ``twin_loop_speed.md``;
4. two short probes of the five baselines' groups trained at once (5 seeds of Hopper 3D each, as
   ``rrls benchmark --device cuda`` packs them) give seconds per learning step; with the
   evaluation's upper bound (every episode at full length, on all the machine's cores), the
   largest budget of ``MENU`` whose whole ``hopper`` preset (5 seeds) fits ``--minutes`` is run
   with ``rrls benchmark``, then ``rrls report`` writes its report, figures and reference file
   -> ``hopper-<steps>/`` (run files without checkpoints);
5. ``runbook.md``: the machine, each step's command, wall time and outcome.

On a short lease, ``--no-preset`` skips step 4 (the longest).

A step that fails is recorded and the next one still runs; the exit status is 1 if any failed.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
MENU = (1_000_000, 500_000, 200_000, 100_000, 50_000)  # steps per run, largest first
TINY_MENU = (400, 200)
SEEDS = 5  # the dry run: 1
ALGOS = ("td3", "dr", "m2td3", "rarl", "nrmdp")  # the dry run: TINY_ALGOS
TINY_ALGOS = ("td3", "rarl")  # one learner, one two-player game (the dynamic evaluation)
SMALL = 5_000_000  # bytes: run files above this (checkpoints, replay buffers) stay out of OUT


class Book:
    """``runbook.md``: one section per step, written as the steps finish (a killed runbook
    keeps what it had)."""

    def __init__(self, out: Path) -> None:
        self.path = out / "runbook.md"
        self.failed: list[str] = []
        self.path.write_text(f"# GPU runbook\n\n{machine()}\n")

    def step(self, title: str, command: list[str], log: Path, timeout: float) -> bool:
        start = time.perf_counter()
        with log.open("w") as f:
            try:
                code = subprocess.run(
                    command, cwd=ROOT, stdout=f, stderr=subprocess.STDOUT, timeout=timeout
                ).returncode
            except subprocess.TimeoutExpired:
                code = "timeout"
        wall = time.perf_counter() - start
        ok = code == 0
        if not ok:
            self.failed.append(title)
        tail = log.read_text().strip().splitlines()[-3:]
        self.write(
            f"## {title}: {'ok' if ok else f'FAILED ({code})'} in {wall:.0f} s\n\n"
            f"`{' '.join(command)}` -> `{log.name}`\n\n" + "".join(f"    {line}\n" for line in tail)
        )
        return ok

    def write(self, text: str) -> None:
        with self.path.open("a") as f:
            f.write(f"\n{text}")
        print(text, flush=True)


def machine() -> str:
    lines = [f"- python {platform.python_version()}, {platform.platform()}"]
    try:
        import torch

        lines.append(f"- torch {torch.__version__}, CUDA available: {torch.cuda.is_available()}")
        if torch.cuda.is_available():
            lines.append(f"- GPU: {torch.cuda.get_device_name(0)}")
    except ImportError:
        lines.append("- torch not installed")
    lines.append(f"- {os.cpu_count()} CPUs")
    return "\n".join(lines) + "\n"


def seconds_per_step(
    device: str, steps: tuple[int, int], seeds: int, tmp: Path, algos: tuple[str, ...] = ALGOS
) -> float:
    """Wall seconds per learning step of the whole preset: the five baselines' groups (``seeds``
    runs each, Hopper 3D) trained at once as ``rrls benchmark`` runs them, at two budgets."""
    walls = []
    for n in steps:
        start = time.perf_counter()
        procs = []
        for algo in algos:
            command = [sys.executable, "-m", "rrls", "train", "--algo", algo, "--task", "hopper"]
            command += ["--uncertainty", "3d", "--seeds", f"0-{seeds - 1}", "--steps", str(n)]
            command += ["--learning-starts", "100", "--eval-every", "0", "--device", device]
            command += ["--out", str(tmp / f"probe-{algo}-{n}"), "--overwrite"]
            procs.append(subprocess.Popen(command, cwd=ROOT, stdout=subprocess.DEVNULL))
        if any(p.wait() for p in procs):
            raise RuntimeError("a probe run failed")
        walls.append(time.perf_counter() - start)
    return max(walls[1] - walls[0], 1e-6) / (steps[1] - steps[0])


def choose(per_step: float, minutes: float, menu: tuple[int, ...], eval_s: float) -> int:
    """The largest budget whose training (the five groups at once) and evaluation fit."""
    for steps in menu:
        if steps * per_step + eval_s <= minutes * 60:
            return steps
    return menu[-1]


def copy_small(bench: Path, dest: Path) -> None:
    """The benchmark's report, reference and run files, without checkpoints."""
    for path in bench.rglob("*"):
        if path.is_file() and path.stat().st_size <= SMALL and "checkpoint" not in path.name:
            target = dest / path.relative_to(bench)
            target.parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(path, target)


def twin_steps(book: Book, args: argparse.Namespace, py: str) -> None:
    """The Warp twin (the ``warp`` extra): physics alone and the whole step per world count,
    each world against CPU MuJoCo, and K stacked TD3 runs trained on it (with a sim-to-sim
    check of one trained policy)."""
    d, tiny = args.device, args.tiny
    worlds = ["2"] if tiny else ["32", "256", "1024", "4096", "8192"]
    physics = [py, "benchmarks/warp_speed.py", "--device", d, "--worlds", *worlds]
    physics += ["--steps", "2", "--tasks", "hopper"] if tiny else []
    book.step("Warp twin: physics alone", physics, args.out / "warp_speed.log", 600)
    whole = [py, "benchmarks/twin_speed.py", "--device", d, "--worlds", *worlds]
    whole += ["--steps", "2", "--tasks", "hopper"] if tiny else []
    book.step("Warp twin: the whole step", whole, args.out / "twin_speed.log", 600)
    check = [py, "benchmarks/twin_check.py", str(args.out / "twin_check"), "--device", d]
    check += ["--no-curves"] + (["--tasks", "invertedpendulum"] if tiny else [])
    book.step("Warp twin vs CPU MuJoCo", check, args.out / "twin_check.log", 900)
    train = [py, "benchmarks/twin_train.py", str(args.out / "twin_train"), "--device", d]
    if tiny:
        train += ["--ks", "1", "--window", "5", "--speed-starts", "10"]
        train += ["--train-steps", "30", "--starts", "10"]
        train += ["--points", "1"]
    book.step("training on the twin", train, args.out / "twin_train.log", 900)
    loop = [py, "benchmarks/twin_loop_speed.py", "--device", d]
    loop += ["--ks", "1", "--steps", "100", "--starts", "20", "--algos", "td3"] if tiny else []
    book.step("rrls train --simulator warp", loop, args.out / "twin_loop_speed.md", 900)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", type=Path, metavar="OUT_DIR")
    parser.add_argument("--device", default="cuda", help="cuda (default) or cpu (a dry run)")
    parser.add_argument("--minutes", type=float, default=20.0, help="the Hopper preset's budget")
    parser.add_argument("--tiny", action="store_true", help="tiny sizes: the CPU dry run")
    parser.add_argument(
        "--no-preset", dest="preset", action="store_false", help="skip the Hopper preset step"
    )
    parser.add_argument(
        "--no-twin", dest="twin", action="store_false", help="skip the Warp twin's steps"
    )
    args = parser.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    book = Book(args.out)
    py = sys.executable
    # the GPU's own tests and the env workers' (many cores here); the rest of the file is CPU
    # work that CI runs anyway (on the first H100, all of it took over 200 s of the lease)
    tests = [py, "-m", "pytest", "-q", "-rs", "tests/test_group.py", "-k", "cuda or worker"]
    tests += ["--collect-only"] if args.tiny else []  # the dry run: the command, not the GPU
    book.step("CUDA tests", tests, args.out / "tests.log", 1200)
    speed = [py, "benchmarks/train_speed.py", "--groups", "--algos", "td3", "m2td3"]
    speed += ["--device", args.device, "--ks", *(["1"] if args.tiny else ["1", "8", "32"])]
    if args.tiny:
        speed += ["--group-steps", "5", "--group-warmup", "5", "--process-steps", "5"]
        speed += ["--learning-starts", "20"]
    seeds = 1 if args.tiny else SEEDS
    book.step("GPU speed table", speed, args.out / "speed.md", 900)
    if args.twin:
        twin_steps(book, args, py)
    if not args.preset:
        book.write(f"## done: {len(book.failed)} step(s) failed {book.failed}\n")
        return 1 if book.failed else 0

    from rrls.experiments.cpu_estimate import estimate
    from rrls.experiments.spec import make_spec

    menu = TINY_MENU if args.tiny else MENU
    with tempfile.TemporaryDirectory(prefix="rrls-runbook-") as tmp:
        try:
            probes, algos = ((150, 200), TINY_ALGOS) if args.tiny else ((1000, 3000), ALGOS)
            per_step = seconds_per_step(args.device, probes, seeds, Path(tmp), algos)
        except RuntimeError as err:
            book.failed.append("probe")
            book.write(f"## probe: FAILED ({err}); the smallest budget is used\n")
            per_step = float("inf")
        spec = make_spec("hopper", seeds=seeds, steps=menu[-1])
        eval_s = estimate(spec, jobs=os.cpu_count() or 1)["eval_s"] / (os.cpu_count() or 1)
        steps = choose(per_step, args.minutes, menu, eval_s)
        book.write(
            f"## budget\n\n{per_step * 1e3:.2f} ms per learning step of the five baselines' "
            f"{seeds}-seed groups at once; "
            f"evaluation <= {eval_s / 60:.1f} min on {os.cpu_count()} CPUs: {steps:,} steps "
            f"per run (menu {', '.join(f'{m:,}' for m in menu)}; {args.minutes:g} min)\n"
        )
        bench = Path(tmp) / f"hopper-{steps}"
        command = [py, "-m", "rrls", "benchmark", "--preset", "hopper", "--out", str(bench)]
        command += ["--seeds", f"0-{seeds - 1}", "--steps", str(steps), "--device", args.device]
        if args.tiny:
            command += ["--learning-starts", "100", "--mesh", "2", "--episodes", "1"]
            command += ["--eval-every", "0", "--algos", ",".join(TINY_ALGOS)]
        ran = book.step("Hopper preset", command, args.out / "hopper.log", 3600)
        if ran:
            report = [py, "-m", "rrls", "report", str(bench), "--export-reference"]
            report += [
                str(bench / "reference.json"),
                "--label",
                f"rrls hopper preset on {args.device} ({seeds} seeds x {steps:,} steps)",
            ]
            book.step("report and reference", report, args.out / "report.log", 600)
        copy_small(bench, args.out / bench.name)
    summary = {"failed": book.failed, "steps": steps, "seconds_per_step": per_step}
    (args.out / "runbook.json").write_text(json.dumps(summary, indent=2) + "\n")
    book.write(f"## done: {len(book.failed)} step(s) failed {book.failed}\n")
    return 1 if book.failed else 0


if __name__ == "__main__":
    sys.exit(main())
