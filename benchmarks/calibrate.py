"""The training rates of `rrls benchmark`'s estimate (each algorithm's row in
`rrls/algorithms.py`: `cpu_steps_per_s`).

Single-thread training rate per algorithm, in CPU time (robust to a loaded machine):
CPU seconds of `rrls train --threads 1` for 3 000 steps (1 000 random) minus for 1 000 random
steps = the CPU cost of 2 000 learning steps; rate = 2000 / that.

    python3 benchmarks/calibrate.py td3 dr rarl nrmdp m2td3 sac

Measure the algorithms side by side in one call: CPU time under load grows with cache
contention, so the ratios of one call hold where its absolute rates do not (RARL's and NR-MDP's
constants are TD3's times such ratios).
"""

import resource
import subprocess
import sys
import tempfile


def cpu(algo: str, steps: int) -> float:
    """CPU seconds of one single-threaded Hopper run of ``steps`` (1 000 of them random)."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    with tempfile.TemporaryDirectory() as out:
        command = [sys.executable, "-m", "rrls", "train", "--algo", algo, "--task", "hopper"]
        command += ["--steps", str(steps), "--learning-starts", "1000", "--threads", "1"]
        command += ["--eval-every", "0", "--out", out, "--overwrite", "--uncertainty", "3d"]
        subprocess.run(command, check=True, capture_output=True)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return (after.ru_utime + after.ru_stime) - (before.ru_utime + before.ru_stime)


if __name__ == "__main__":
    td3 = None
    for algo in sys.argv[1:] or ["td3", "dr", "rarl", "nrmdp", "m2td3", "sac"]:
        full, random = cpu(algo, 3000), cpu(algo, 1000)
        rate = 2000 / (full - random)
        td3 = rate if algo == "td3" else td3
        ratio = f" ({rate / td3:.2f}x TD3's)" if td3 and algo != "td3" else ""
        print(f"{algo}: {rate:.0f} learning steps per CPU-second{ratio}", flush=True)
