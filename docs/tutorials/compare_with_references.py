"""Tutorial (c): compare your method with shipped reference results, without re-training the
baselines.

    python3 -m pip install -c constraints.txt ".[sb3,eval]"   # in the rrls checkout
    python docs/tutorials/compare_with_references.py --steps 20000 --seeds 0-1
    python docs/tutorials/compare_with_references.py --steps 200 --seeds 0      # seconds

A reference file holds what someone measured under one protocol — per task, set and algorithm
the worst / average case over seeds — with the physics, mesh, episodes and budget it was
measured on. rrls ships two:

- ``paper``: the RRLS paper's tables. They were produced on *other physics* (v4 envs, the
  original code's parameter writes, the ``np.arange`` mesh; docs/differences.md), so rrls refuses
  them as a reference for a benchmark on its own physics — they are context, not a yardstick.
- ``quick``: TD3, DR, RARL, NR-MDP and M2TD3 trained and evaluated by rrls itself with the
  ``quick`` preset (InvertedPendulum, 1D set, 30 k steps, 64-64 networks, mesh 10 x 5 episodes,
  3 seeds).

Your method is submitted into an empty benchmark with the reference's protocol and the report
normalises it with the reference's TD3 and M2TD3, and compares it with the reference's rows.
The same from the shell:

    rrls submit mine --preset quick --algo my-sac --task invertedpendulum --seed 0 agent.zip
    rrls report mine --reference quick
    rrls report bench --export-reference lab.json     # share your own baselines as a file
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from rrls.seeds import parse_seeds


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=20_000, help="SAC steps per seed")
    parser.add_argument(
        "--seeds", type=parse_seeds, default=[0, 1], help="seeds of your method: 0-1, 0,3 or 4"
    )
    parser.add_argument("--reference", default="quick", help="a shipped name or a file")
    parser.add_argument("--bench", default="bench-mine", help="benchmark directory to create")
    parser.add_argument("--name", default="my-sac", help="your method's name in the report")
    args = parser.parse_args(argv)

    import gymnasium as gym
    import torch
    from stable_baselines3 import SAC

    import rrls  # noqa: F401  (registers the rrls/ ids)
    from rrls.benchmark.store import build_store
    from rrls.report.reference import ReferenceError, check_compatible, load_reference
    from rrls.report.writer import make_report
    from rrls.submissions import submit
    from rrls.submissions.steps import create_benchmark

    # 1. What ships. The paper's numbers: context only (other physics).
    paper = load_reference("paper")
    print(
        f"{paper.label!r} ({paper.physics}): M2TD3 on Hopper, worst case "
        f"{paper.mean('hopper', '3d', 'm2td3', 'worst_case'):.1f} (paper Table 7)"
    )
    ref = load_reference(args.reference)
    print(f"reference {ref.label!r}: physics {ref.physics}, set(s) {', '.join(ref.sets)}, mesh "
          f"{ref.mesh} x {ref.episodes} episodes, {ref.steps or '?'} steps, "
          f"algorithms {', '.join(ref.algorithms())}")  # fmt: skip
    uncertainty = ref.sets[0]
    task = ref.tasks(uncertainty)[0]

    # 2. An empty benchmark with the reference's protocol (no baselines trained here).
    bench = Path(args.bench)
    if not (bench / "benchmark.json").exists():
        create_benchmark(
            bench,
            "quick",
            (task,),
            uncertainty=uncertainty,
            mesh=ref.mesh,
            episodes=ref.episodes,
            steps=ref.steps,
        )
    spec = json.loads((bench / "benchmark.json").read_text())
    check_compatible(ref, spec)  # what `rrls report --reference` checks
    try:
        check_compatible(paper, spec)
    except ReferenceError as err:
        print(f"the paper's tables are refused here, as they should be: {err}")

    # 3. Your method: here SAC (Stable-Baselines3) with domain randomisation over the set, one
    #    agent per seed; any policy works (a callable, an nn.Module, a .zip, module:attribute).
    torch.set_num_threads(1)  # SB3's default (a thread per core) oversubscribes a shared machine
    for seed in args.seeds:
        env = gym.make(f"rrls/robust-{task}-domain-randomization-{uncertainty}-v0")
        model = SAC(
            "MlpPolicy",
            env,
            seed=seed,
            learning_starts=min(1_000, args.steps // 2),
            policy_kwargs={"net_arch": [64, 64]},
        )
        model.learn(total_timesteps=args.steps)
        done = submit(bench, args.name, task, seed, model, steps=args.steps)  # its budget
        print(f"seed {seed}: worst case {done.worst_case:.1f}, average {done.average_case:.1f}")

    # 4. The report: normalised with the reference's TD3 / M2TD3 (it says so), the probability
    #    of improvement over the reference's TD3 seeds, and the reference's rows beside yours.
    build_store(bench)
    report = make_report(bench, plots=False, reference=ref)
    summary = json.loads((bench / "report" / "summary.json").read_text())
    cell = summary["results"][task][args.name]
    norm = cell["normalised"]["worst_case"]
    poi = summary["aggregate"][args.name].get("poi_over_td3_worst_case", {})
    print(f"normalised by: {summary['normalisation'][task]['worst_case']} ({ref.label})")
    if norm is not None:
        print(f"{args.name}: normalised worst case {norm['mean']:.2f} ± {norm['std']:.2f}")
    if poi.get("value") is not None:
        print(f"P({args.name} better than the reference's TD3, worst case) = {poi['value']:.2f}")
    for algo in ref.algorithms():
        v = ref.mean(task, uncertainty, algo, "worst_case")
        print(f"  reference {algo:<8} worst case {v:8.1f}")
    print(f"  {args.name:<18} worst case {cell['worst_case']['mean']:8.1f}")
    print(f"report: {report}")
    return summary


if __name__ == "__main__":
    main()
