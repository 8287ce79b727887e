"""Re-evaluate a results folder's finished runs under a preset's protocol, without training.

    python3 benchmarks/reevaluate.py docs/results/hopper-200k /path/to/new-bench \
        --preset hopper-200k --algos td3,dr,nrmdp

When a preset's evaluation protocol changes (the hopper-200k preset, then named hopper, moved to
the paper's ``np.arange`` mesh) the trained policies stay valid: each run's ``policy.npz``,
``run.json``, curves and adversary are copied into a benchmark directory written with the
preset's protocol today, the final mesh evaluation runs again there (``stages.run_evaluation``,
the benchmark's own code path) and ``result.json`` is written anew. The dynamic evaluation does
not depend on the mesh: its ``dynamic.csv`` and fields are kept. ``rrls benchmark --preset P
--out DEST`` then trains only what is missing (the runs whose training changed), and ``rrls
report DEST`` reports all of them. A run whose training hyper-parameters differ from the
preset's today is refused: it needs training again, not a re-evaluation — unless
``--keep-training`` says to re-evaluate it as trained (an interim reference whose page names the
difference; ``result.json`` then records ``trained_otherwise``, what differs).
"""

from __future__ import annotations

import argparse
import shutil
import time
from pathlib import Path

from rrls import files, rundir
from rrls.benchmark import benchfile
from rrls.benchmark.grid import RunKey, make_spec
from rrls.benchmark.stages import run_evaluation
from rrls.evaluation import MLPPolicy

COPIED = ("policy.npz", "adversary.npz", "run.json", "scalars.csv", "dynamic.csv")
DYNAMIC = ("dynamic_mean", "dynamic_std", "dynamic_env")


def reevaluate(
    src: Path, dest: Path, preset: str, algos: list[str], workers: int, keep: bool = False
) -> list[str]:
    """The names of the runs re-evaluated into ``dest`` (those already there are skipped)."""
    spec = make_spec(preset)
    dest.mkdir(parents=True, exist_ok=True)
    benchfile.write_spec(dest, spec)
    done = []
    for key in spec.runs():
        if key.algo not in algos:
            continue
        name = key.name(spec.uncertainty)
        old, new = src / "runs" / name, dest / "runs" / name
        if (new / rundir.RESULT).exists() or not (old / rundir.RESULT).exists():
            continue
        differ = _training_differences(spec, key, old)
        if differ and not keep:
            raise SystemExit(f"{name} was trained otherwise ({differ}): train it again")
        new.mkdir(parents=True, exist_ok=True)
        for rel in COPIED:
            for path in (old / rel, old / f"{rel}{files.SEAL_SUFFIX}"):
                if path.is_file():
                    shutil.copy2(path, new / path.name)
        before = files.read_checked_json(old / rundir.RESULT)
        start = time.time()
        policy = MLPPolicy.load(new / rundir.POLICY)
        trained = {"train_set": spec.train_set(key.algo), "steps": spec.steps}
        result = run_evaluation(
            spec, key.algo, key.task, key.seed, policy, new, workers, False, trained
        )
        result.update({k: before[k] for k in DYNAMIC if k in before})
        # the training's seconds as first recorded, plus this evaluation's
        result["seconds"] = float(before.get("seconds", 0.0)) + time.time() - start
        if differ:
            result["trained_otherwise"] = {k: v[0] for k, v in differ.items()}
        files.write_checked_json(new / rundir.RESULT, result)
        print(
            f"{name}: worst {before['worst_case']:.1f} -> {result['worst_case']:.1f}, "
            f"average {before['average_case']:.1f} -> {result['average_case']:.1f}",
            flush=True,
        )
        done.append(name)
    return done


def _training_differences(spec, key: RunKey, run: Path) -> dict:
    """``{hyper-parameter: (the run's, the preset's today)}`` where they differ."""
    hyper = rundir.read_run_json(run)["config"]["hyper"]  # any run.json format
    today = spec.hyperparameters(key.algo)
    differ = {
        k: (hyper.get(k), v)
        for k, v in today.items()
        if (list(v) if isinstance(v, tuple) else v) != hyper.get(k)
    }
    if key.algo == "rarl" and hyper.get("schedule", "alternating") != "simultaneous":
        differ["schedule"] = (hyper.get("schedule", "alternating"), "simultaneous")
    return differ


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument(
        "src", type=Path, help="a results folder with runs/ (e.g. docs/results/hopper-200k)"
    )
    parser.add_argument("dest", type=Path, help="the benchmark directory to write")
    parser.add_argument("--preset", required=True)
    parser.add_argument("--algos", required=True, help="comma-separated")
    parser.add_argument("--workers", type=int, default=1)
    parser.add_argument(
        "--keep-training", action="store_true", help="re-evaluate runs trained otherwise"
    )
    args = parser.parse_args()
    algos = args.algos.split(",")
    names = reevaluate(args.src, args.dest, args.preset, algos, args.workers, args.keep_training)
    print("\n".join(names) if names else "nothing to re-evaluate")
