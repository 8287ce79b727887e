"""What do the details of NR-MDP's and M2TD3's authors' code that rrls leaves off by default
change? Each variant with all of them on (``authors_variants``: Tessler's pooled observation
standardisation and critic L2 term; the M2TD3 authors' unclipped exploration and one start
state per run) trained as the ``halfcheetah`` reference's runs, on the same seeds, beside them.

    python benchmarks/ablation.py --run --out /work/bench-hc-ablation   # 4 runs, ~9 CPU-hours
    python benchmarks/ablation.py --out /work/bench-hc-ablation         # the table only

``--run`` is ``rrls benchmark --preset halfcheetah`` with the two variants and ``--seeds``
(resumable: run it again). The table reads the variants' ``result.json``/``scalars.csv`` and the
reference's runs of the same seeds (``docs/results/halfcheetah/runs``), prints the ratio table
and writes ``docs/results/halfcheetah/ablation.csv`` (one row per algorithm, variant and seed).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import pandas as pd

sys.path.insert(0, str(Path(__file__).resolve().parent))
from authors_variants import VARIANTS, register

if __name__ in ("__main__", "__mp_main__"):  # the driver, and the benchmark's spawned processes
    register()

ROOT = Path(__file__).resolve().parent.parent
REFERENCE = ROOT / "docs" / "results" / "halfcheetah" / "runs"
OUT = ROOT / "docs" / "results" / "halfcheetah" / "ablation.csv"
METRICS = ("worst_case", "average_case", "nominal")
NAMES = {
    "worst_case": "worst case",
    "average_case": "average case",
    "nominal": "final nominal return",
}


def run_row(run: Path) -> dict[str, float]:
    """A finished run's worst and average case (the mesh) and its last nominal evaluation."""
    result = json.loads((run / "result.json").read_text())
    scalars = pd.read_csv(run / "scalars.csv")
    nominal = scalars[scalars.metric == "eval/nominal_return"].sort_values("step")
    return {
        "worst_case": float(result["worst_case"]),
        "average_case": float(result["average_case"]),
        "nominal": float(nominal.value.iloc[-1]),
        "steps": int(result["steps"]),
    }


def collect(out: Path, reference: Path = REFERENCE) -> pd.DataFrame:
    """One row per (algorithm, variant, seed) whose variant run has finished, with its
    reference run of the same seed (``variant``: "rrls" or "authors")."""
    rows = []
    for algo, info in VARIANTS.items():
        for run in sorted((out / "runs").glob(f"{info.name}-halfcheetah-3d-seed*")):
            if not (run / "result.json").exists():
                continue
            seed = int(run.name.rsplit("seed", 1)[1])
            base = reference / f"{algo}-halfcheetah-3d-seed{seed}"
            if not (base / "result.json").exists():
                continue
            for variant, path in (("rrls", base), ("authors", run)):
                rows.append({"algorithm": algo, "variant": variant, "seed": seed, **run_row(path)})
    return pd.DataFrame(rows, columns=["algorithm", "variant", "seed", *METRICS, "steps"])


def table(frame: pd.DataFrame) -> str:
    """Per algorithm and metric: rrls's default and the authors' details, mean ± std over the
    paired seeds (one seed: its value alone; a std of one value says nothing), their ratio and
    each seed's difference."""
    lines = [
        "| algorithm | metric | seeds | rrls default | authors' details | authors / rrls "
        "| per seed (authors - rrls) |",
        "|---|---|---|---|---|---|---|",
    ]
    for algo, group in frame.groupby("algorithm", sort=False):
        wide = group.pivot(index="seed", columns="variant", values=list(METRICS))
        n = len(wide)
        for metric in METRICS:
            a, b = wide[metric]["rrls"].to_numpy(), wide[metric]["authors"].to_numpy()
            diffs = ", ".join(f"{d:+.0f}" for d in b - a)
            ratio = b.mean() / a.mean() if a.mean() else float("nan")
            cells = [
                f"{x.mean():.0f} ± {x.std(ddof=1):.0f}" if n > 1 else f"{x.mean():.0f}"
                for x in (a, b)
            ]
            lines.append(
                f"| {VARIANTS[algo].display} | {NAMES[metric]} | {n} | {cells[0]} | {cells[1]} "
                f"| {ratio:.2f} | {diffs} |"
            )
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", type=Path, required=True, help="the variants' benchmark dir")
    parser.add_argument("--run", action="store_true", help="train and evaluate them first")
    parser.add_argument("--seeds", default="0-1", help="the seeds (default: 0-1)")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--preset", default="halfcheetah", help="smoke: seconds, to try it")
    parser.add_argument("--csv", type=Path, default=OUT, help=f"(default: {OUT})")
    args = parser.parse_args(argv)
    if args.run:
        from rrls.cli import main as rrls

        algos = ",".join(info.name for info in VARIANTS.values())
        code = rrls(
            [
                "benchmark",
                "--preset",
                args.preset,
                "--tasks",
                "halfcheetah",
                "--algos",
                algos,
                "--seeds",
                args.seeds,
            ]
            + ["--out", str(args.out), "--workers", str(args.workers), "--yes"]
        )
        if code:
            return code
    frame = collect(args.out)
    if frame.empty:
        print(f"no finished variant run with a reference run of its seed under {args.out}")
        return 1
    args.csv.parent.mkdir(parents=True, exist_ok=True)
    tmp = args.csv.with_suffix(".tmp")
    frame.to_csv(tmp, index=False, float_format="%.6g")
    tmp.replace(args.csv)
    print(table(frame))
    print(f"wrote {args.csv}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
