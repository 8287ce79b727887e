"""Training on the Warp twin: aggregated env steps/s of K stacked TD3 runs, and a sim-to-sim
check of one policy trained on the twin, evaluated on CPU MuJoCo and on the twin at the same
points.

    python3 benchmarks/twin_train.py OUT --device cuda --ks 1 32 128 --train-steps 60000
    python3 benchmarks/twin_train.py OUT --device cpu --ks 2 --window 20 --train-steps 300  # dry

Speed: ``train_on_twin("td3", task, seeds=range(K))`` with ``learning_starts`` ``--speed-starts``
(1 000); the clock runs over the ``--window`` steps after ``starts + 2 * window`` (the first
updates capture their CUDA graphs; the CPU dry run takes 10, since a twin step on warp's CPU
device takes ~0.15 s). Sim-to-sim: one TD3 run of ``--train-steps`` on the twin (nominal model;
``--starts`` random steps first), then
``--points`` points of the task's largest set, one episode each (deterministic policy): the
return on CPU MuJoCo (float64, rrls's evaluation physics) and on the twin (float32), both from
the twin's reset state of that world.
"""

from __future__ import annotations

import argparse
import csv
import time
import warnings
from pathlib import Path

import numpy as np

from rrls.agents.on_twin import train_on_twin
from rrls.envs import resolve
from rrls.twin import WarpTwin
from rrls.twin.agreement import cpu_env_at
from rrls.twin.env import default_set

STARTS = 1000


def speed(task: str, k: int, window: int, device: str, starts: int = STARTS) -> float:
    marks: dict[int, float] = {}

    def mark(step: int, _returns: object) -> None:
        marks[step] = time.perf_counter()

    steps = starts + 3 * window
    train_on_twin(
        "td3",
        task,
        seeds=tuple(range(k)),
        steps=steps,
        device=device,
        hyper={"learning_starts": starts},
        on_progress=mark,
        progress_every=window,
    )
    a, b = starts + 2 * window, starts + 3 * window
    return k * window / (marks[b] - marks[a])


def sim_to_sim(
    task: str, steps: int, starts: int, n_points: int, device: str, out: Path
) -> list[tuple]:
    """Train one TD3 run on the twin (the library loop), then ``both_physics`` at its points."""
    hyper = {"learning_starts": starts}
    result = train_on_twin("td3", task, seeds=(0,), steps=steps, device=device, hyper=hyper)
    policy = result.policies[0]
    policy.save(out / f"td3-{task}-twin-{steps}.npz")
    return both_physics(policy, task, n_points, device)


def both_physics(policy: object, task: str, n_points: int, device: str) -> list[tuple]:
    """``policy``'s return, one episode per point of ``n_points`` drawn from the task's largest
    set (seeded), on the twin and on CPU MuJoCo from the same first state (the twin's reset)."""
    resolved = resolve(task, default_set(task))
    rng = np.random.default_rng(1)
    points = np.asarray(resolved.box.sample(rng, n_points)).reshape(n_points, -1)
    twin = WarpTwin(task, n_points, resolved.box, points=points, device=device, seed=5)
    obs, _ = twin.reset()
    qpos, qvel = twin.state()
    twin_ret = np.zeros(n_points)
    done = np.zeros(n_points, dtype=bool)
    while not done.all():
        obs, r, term, trunc, _ = twin.step(policy(obs).astype(np.float32))
        twin_ret += np.where(done, 0.0, r)
        done |= term | trunc
    rows = []
    for w in range(n_points):
        env = cpu_env_at(resolved, points[w], qpos[w], qvel[w])
        o, ret = env.unwrapped._get_obs(), 0.0
        for _ in range(twin.max_episode_steps):
            o, r, term, _, _ = env.step(policy(o[None])[0])
            ret += r
            if term:
                break
        rows.append((points[w].tolist(), ret, float(twin_ret[w])))
    return rows


def markdown(names: list[str], rows: list[tuple]) -> str:
    """The sim-to-sim table in markdown (what the docs show, generated from the CSV)."""
    lines = [
        f"| {', '.join(names)} | return on CPU MuJoCo | return on the twin | twin / CPU |",
        "|---|---|---|---|",
    ]
    for point, cpu, tw in rows:
        ratio = tw / cpu if cpu else float("nan")
        shown = ", ".join(f"{x:.2f}" for x in point)
        lines.append(f"| {shown} | {cpu:.1f} | {tw:.1f} | {ratio:.2f} |")
    return "\n".join(lines) + "\n"


def markdown_from_csv(path: Path) -> str:
    """``markdown`` of a ``sim_to_sim.csv`` this script wrote."""
    with open(path, newline="") as f:
        reader = csv.reader(f)
        header = next(reader)
        names = header[:-2]
        rows = [([float(x) for x in r[:-2]], float(r[-2]), float(r[-1])) for r in reader]
    return markdown(names, rows)


def _print_rows(rows: list[tuple], names: list[str], out: Path) -> None:
    print(markdown(names, rows), end="")
    with open(out / "sim_to_sim.csv", "w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow([*names, "cpu_return", "twin_return"])
        for point, cpu, tw in rows:
            writer.writerow([*point, cpu, tw])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", type=Path)
    parser.add_argument("--device", default="cuda")
    parser.add_argument("--task", default="hopper")
    parser.add_argument("--ks", nargs="+", type=int, default=[1, 32, 128])
    parser.add_argument("--window", type=int, default=500)
    parser.add_argument("--train-steps", type=int, default=60_000)
    parser.add_argument("--points", type=int, default=10)
    parser.add_argument("--starts", type=int, default=5000, help="sim-to-sim run's warm-up")
    parser.add_argument("--speed-starts", type=int, default=STARTS, help="speed runs' warm-up")
    parser.add_argument(
        "--policy",
        type=Path,
        help="an `rrls train --simulator warp` run directory: its policy's sim-to-sim check "
        "alone (no speed rows, no training here)",
    )
    args = parser.parse_args()
    warnings.simplefilter("ignore")
    args.out.mkdir(parents=True, exist_ok=True)
    if args.policy is not None:
        from rrls.evaluation import load_policy

        policy = load_policy(args.policy / "policy.npz")
        task = policy.metadata["task"]
        print(f"sim-to-sim: {args.policy} ({policy.metadata.get('simulator', 'mujoco')}-trained)")
        rows = both_physics(policy, task, args.points, args.device)
        _print_rows(rows, list(resolve(task, default_set(task)).box.names), args.out)
        return
    print("| algo | task | K | aggregated env steps/s | per run |")
    print("|---|---|---|---|---|")
    for k in args.ks:
        rate = speed(args.task, k, args.window, args.device, args.speed_starts)
        print(f"| td3 | {args.task} | {k} | {rate:,.0f} | {rate / k:,.0f} |", flush=True)
    if args.train_steps:
        start = time.perf_counter()
        rows = sim_to_sim(
            args.task, args.train_steps, args.starts, args.points, args.device, args.out
        )
        print(
            f"\nsim-to-sim: TD3, {args.train_steps} steps on the twin "
            f"(learning_starts {args.starts}) "
            f"({time.perf_counter() - start:.0f} s with the evaluation)"
        )
        names = list(resolve(args.task, default_set(args.task)).box.names)
        _print_rows(rows, names, args.out)


if __name__ == "__main__":
    main()
