"""``rrls train --simulator warp`` measured: aggregated env steps/s of K stacked runs of the
training loop itself (checkpoints off, periodic evaluations off) on the Warp twin, against the
same command on CPU MuJoCo, for TD3 and M2TD3.

    python3 benchmarks/twin_loop_speed.py --device cuda --ks 1 32 128 --steps 3000
    python3 benchmarks/twin_loop_speed.py --device cpu --ks 1 --steps 100 --starts 20  # dry

Each cell is one ``rrls train`` process; its rate is the loop's own clock (run 0's
``charts/steps_per_second`` at each episode end) between the first episode end after the
warm-up and the first updates, which capture their CUDA graphs, and the last, times K
(``gpu_runbook.rate_from_scalars``). Prints a markdown table.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from gpu_runbook import rate_from_scalars


def rate(algo: str, task: str, k: int, simulator: str, args: argparse.Namespace) -> float:
    with tempfile.TemporaryDirectory(prefix="rrls-twin-loop-") as tmp:
        out = Path(tmp) / "runs"
        command = [sys.executable, "-m", "rrls", "train", "--algo", algo, "--task", task]
        command += ["--seeds", f"0-{k - 1}", "--steps", str(args.steps), "--out", str(out)]
        command += ["--learning-starts", str(args.starts), "--eval-every", "0"]
        command += ["--checkpoint-every", str(10 * args.steps), "--device", args.device]
        command += ["--simulator", simulator]
        done = subprocess.run(command, capture_output=True, text=True)
        if done.returncode != 0:
            raise RuntimeError(done.stderr.strip().splitlines()[-1])
        # the window starts after the first updates (learning starts plus one block of 64)
        per_run, _ = rate_from_scalars(out / "seed0" / "scalars.csv", args.starts + 64)
        return k * per_run


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--device", default="cuda")
    parser.add_argument("--task", default="hopper")
    parser.add_argument("--algos", nargs="+", default=["td3", "m2td3"])
    parser.add_argument("--ks", nargs="+", type=int, default=[1, 32, 128])
    parser.add_argument("--steps", type=int, default=3000)
    parser.add_argument("--starts", type=int, default=1000)
    parser.add_argument("--no-cpu", dest="cpu", action="store_false", help="the twin's rows only")
    args = parser.parse_args()
    print("| algo | task | K | twin: env steps/s | CPU MuJoCo: env steps/s | twin / CPU |")
    print("|---|---|---|---|---|---|")
    for algo in args.algos:
        for k in args.ks:
            twin = rate(algo, args.task, k, "warp", args)
            cpu = rate(algo, args.task, k, "mujoco", args) if args.cpu else float("nan")
            print(
                f"| {algo} | {args.task} | {k} | {twin:,.0f} | {cpu:,.0f} | {twin / cpu:.2f} |",
                flush=True,
            )


if __name__ == "__main__":
    main()
