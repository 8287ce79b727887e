"""Tutorial (a): train a Stable-Baselines3 agent with domain randomisation, evaluate it over the
Hopper 3D uncertainty set, submit it into a benchmark and get its column in the report.

    python3 -m pip install -c constraints.txt ".[sb3,eval]"   # in the checkout: SB3 (+ torch), ...
    python docs/tutorials/submit_sb3_agent.py --steps 100000 --bench bench-hopper
    python docs/tutorials/submit_sb3_agent.py --steps 200 --mesh 2 --episodes 1   # seconds

The same from the shell, once the agent is saved:

    rrls evaluate sac-hopper.zip --task hopper --uncertainty 3d      # worst / average case
    rrls submit bench-hopper --algo sb3-sac-dr --task hopper --seed 0 sac-hopper.zip
    rrls report bench-hopper          # sb3-sac-dr beside TD3, DR, M2TD3, ... in every table

``bench-hopper`` is a ``rrls benchmark --out bench-hopper --tasks hopper ...`` directory (its
baselines are trained there), or, as this script does when it does not exist, an empty benchmark
with the paper's protocol (``rrls submit --preset paper``): the report then has no TD3/M2TD3 of
its own to normalise with — pass ``rrls report DIR --reference FILE`` (tutorial c).

Loading an SB3 ``.zip`` unpickles its classes (cloudpickle): submit only files you trust.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=100_000, help="SAC training steps")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--bench", default="bench-hopper", help="benchmark directory")
    parser.add_argument("--out", default=".", help="where to save the agent")
    parser.add_argument("--mesh", type=int, default=10, help="new benchmark: points per dim")
    parser.add_argument("--episodes", type=int, default=5, help="new benchmark: episodes/point")
    parser.add_argument("--name", default="sb3-sac-dr", help="the algorithm's name in the report")
    parser.add_argument(
        "--threads",
        type=int,
        default=1,
        help="torch threads (default 1: more oversubscribe a shared machine)",
    )
    args = parser.parse_args(argv)

    import gymnasium as gym
    import torch
    from stable_baselines3 import SAC

    import rrls  # noqa: F401  (registers the rrls/ ids)
    from rrls.benchmark.store import build_store
    from rrls.evaluation import Protocol, evaluate
    from rrls.report.writer import make_report
    from rrls.submissions import submit
    from rrls.submissions.steps import create_benchmark

    # SB3 trains with torch's default of one thread per core; on a machine shared with other
    # work (or with few cores) those threads oversubscribe it and a 200-step smoke run takes
    # minutes instead of seconds.
    torch.set_num_threads(args.threads)

    # 1. Train: SAC on Hopper whose torso, thigh masses and friction are redrawn every episode
    #    from the paper's 3D set (DomainRandomization inside the registered id).
    env = gym.make("rrls/robust-hopper-domain-randomization-3d-v0")
    model = SAC("MlpPolicy", env, seed=args.seed, learning_starts=min(10_000, args.steps // 2))
    model.learn(total_timesteps=args.steps)
    path = Path(args.out) / "sac-hopper.zip"
    model.save(path)
    print(f"trained SAC for {args.steps} steps: {path}")

    # 2. Evaluate: worst and average case over a uniform mesh of the 3D set (the model or the
    #    zip both work: rrls adapts SB3 models, acting deterministically).
    protocol = Protocol("3d", mesh=args.mesh, episodes=args.episodes, seed=0)
    result = evaluate(model, "hopper", protocol)
    print(f"worst case {result.worst_case:.1f} at {result.worst_point}")
    print(f"average case {result.average_case:.1f}")

    # 3. Submit into a benchmark: evaluated under *its* protocol (set, mesh, episodes, episode
    #    seeds), stored as a run of algorithm `--name`, with the zip's SHA-256 as provenance.
    bench = Path(args.bench)
    if not (bench / "benchmark.json").exists():
        create_benchmark(bench, "paper", ("hopper",), mesh=args.mesh, episodes=args.episodes)
    done = submit(bench, args.name, "hopper", args.seed, str(path), steps=args.steps)
    state = "submitted" if done.evaluated else "already submitted"
    print(f"{state}: {done.run_dir} (worst case {done.worst_case:.1f})")

    # 4. Report: the submitted algorithm is a row of every table and a line of every figure.
    build_store(bench)
    report = make_report(bench, plots=False)
    summary = json.loads((bench / "report" / "summary.json").read_text())
    cell = summary["results"]["hopper"][args.name]
    print(f"report: {report}")
    print(
        f"{args.name}: worst case {cell['worst_case']['mean']:.1f}, average case "
        f"{cell['average_case']['mean']:.1f} over {cell['worst_case']['n_seeds']} seed(s)"
    )
    return summary


if __name__ == "__main__":
    main()
