"""MuJoCo Warp with a parameter point per world: env steps/s, and each world's agreement with
CPU MuJoCo at its own point.

    python3 benchmarks/warp_speed.py --device cuda --worlds 32 256 1024 4096 8192   # a GPU
    python3 benchmarks/warp_speed.py --device cpu --worlds 8 --steps 20              # warp's CPU

Each world gets its own point of the task's uncertainty set (uniform draws from ``--seed``). The
per-world model fields are not recomputed on the device: a CPU env writes each point with
``set_params`` (rrls's convention, ``mj_setConst`` after mass writes) and its model's fields,
derived constants included, are copied into MJWarp's batched fields. That is the Warp twin's
parameter path; what this script adds is the timing and the check against CPU MuJoCo.

Speed: ``frame_skip`` physics steps per env step, the same random action held per world (no
resets: a fallen Hopper still has its contacts), captured in a CUDA graph on a GPU. Agreement:
worlds 0..7 from the same initial state and actions as a CPU env at the same point; the largest
``|qpos - qpos_cpu|`` after 1, 10 and 100 env steps (float32 against float64).
"""

from __future__ import annotations

import argparse
import time

import gymnasium as gym
import mujoco
import numpy as np

import rrls  # noqa: F401  (registers the envs)
from rrls.envs import get_uncertainty_set
from rrls.twin.points import MODEL_FIELDS as FIELDS

IDS = {"hopper": "rrls/robust-hopper-v0", "halfcheetah": "rrls/robust-halfcheetah-v0"}


def points(task: str, uncertainty: str, n: int, seed: int) -> list[dict[str, float]]:
    box = get_uncertainty_set(task, uncertainty)
    rng = np.random.default_rng(seed)
    draws = rng.uniform(np.asarray(box.low), np.asarray(box.high), size=(n, box.dim))
    return [dict(zip(box.names, row.tolist(), strict=True)) for row in draws]


def world_fields(env, pts: list[dict[str, float]]) -> dict[str, np.ndarray]:
    """Each world's copy of FIELDS (and the timestep), read from the CPU model at its point."""
    out: dict[str, list[np.ndarray]] = {f: [] for f in FIELDS}
    out["timestep"] = []
    for p in pts:
        env.set_params(**p)
        for f in FIELDS:
            out[f].append(np.array(getattr(env.model, f), copy=True))
        out["timestep"].append(np.array(env.model.opt.timestep))
    env.reset_params()
    return {k: np.stack(v) for k, v in out.items()}


def warp_model(mjw, wp, mjm: mujoco.MjModel, fields: dict[str, np.ndarray]):
    n = len(fields["body_mass"])
    m = mjw.put_model(mjm, batch_sizes={f: n for f in FIELDS})
    for f in FIELDS:
        arr = getattr(m, f)
        values = fields[f].astype(np.float32)
        if f == "actuator_gear":
            values = values.reshape(n, -1, 6)
        arr.assign(values.reshape(arr.shape + (-1,)) if values.ndim > arr.ndim else values)
    return m


def initial_state(mjm: mujoco.MjModel, n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed + 1)
    qpos = mjm.qpos0[None] + rng.uniform(-5e-3, 5e-3, size=(n, mjm.nq))
    qvel = rng.uniform(-5e-3, 5e-3, size=(n, mjm.nv))
    return qpos, qvel


def run(args: argparse.Namespace) -> None:
    import mujoco_warp as mjw
    import warp as wp

    wp.config.quiet = True
    wp.init()
    device = wp.get_device(args.device)
    print(
        f"warp {wp.__version__}, mujoco_warp {getattr(mjw, '__version__', '?')}, "
        f"device {device.name}",
        flush=True,
    )
    rows = []
    for task in args.tasks:
        env = gym.make(IDS[task]).unwrapped
        mjm, skip = env.model, env.frame_skip
        for n in args.worlds:
            pts = points(task, args.uncertainty, n, args.seed)
            fields = world_fields(env, pts)
            with wp.ScopedDevice(device):
                m = warp_model(mjw, wp, mjm, fields)
                mjd = mujoco.MjData(mjm)
                d = mjw.put_data(mjm, mjd, nworld=n, nconmax=args.nconmax, njmax=args.njmax)
                qpos, qvel = initial_state(mjm, n, args.seed)
                d.qpos.assign(qpos.astype(np.float32))
                d.qvel.assign(qvel.astype(np.float32))
                rng = np.random.default_rng(args.seed + 2)
                ctrl = rng.uniform(-1, 1, size=(n, mjm.nu)).astype(np.float32)
                d.ctrl.assign(ctrl)
                start = time.perf_counter()
                for _ in range(skip):  # the first call compiles (cached on disk after)
                    mjw.step(m, d)
                wp.synchronize()
                first = time.perf_counter() - start
                checks = agreement(env, mjm, d, pts, qpos, qvel, ctrl, skip, m, mjw, wp)
                graph = None
                if device.is_cuda:
                    with wp.ScopedCapture() as cap:
                        for _ in range(skip):
                            mjw.step(m, d)
                    graph = cap.graph
                for _ in range(3):
                    launch(graph, m, d, skip, mjw, wp)
                wp.synchronize()
                start = time.perf_counter()
                for _ in range(args.steps):
                    launch(graph, m, d, skip, mjw, wp)
                wp.synchronize()
                wall = time.perf_counter() - start
            rate = n * args.steps / wall
            ncon = int(d.nacon.numpy()[0]) if hasattr(d, "nacon") else -1
            rows.append((task, n, rate, first, ncon, checks))
            print(
                f"{task} worlds={n}: {rate:,.0f} env steps/s ({args.steps} env steps x {skip} "
                f"physics steps, {wall:.2f} s); first step {first:.1f} s; contacts now {ncon}; "
                f"max |dqpos| vs CPU MuJoCo after 1/10/100 env steps: "
                + " / ".join(f"{c:.1e}" for c in checks),
                flush=True,
            )
        cpu = cpu_rate(env, skip, args.seed)
        print(f"{task}: CPU MuJoCo (one thread, this machine): {cpu:,.0f} env steps/s", flush=True)
        rows.append((task, 0, cpu, 0.0, -1, ()))
    print("\n| task | worlds | env steps/s | vs CPU MuJoCo (1 thread) | max dqpos 1 / 10 / 100 |")
    print("|---|---|---|---|---|")
    base = {r[0]: r[2] for r in rows if r[1] == 0}
    for task, n, rate, _, _, checks in rows:
        if n:
            c = " / ".join(f"{x:.1e}" for x in checks)
            print(f"| {task} | {n} | {rate:,.0f} | {rate / base[task]:.1f}x | {c} |")


def launch(graph, m, d, skip, mjw, wp) -> None:
    if graph is not None:
        wp.capture_launch(graph)
    else:
        for _ in range(skip):
            mjw.step(m, d)


def agreement(env, mjm, d, pts, qpos, qvel, ctrl, skip, m, mjw, wp) -> tuple[float, ...]:
    """Largest |qpos - CPU qpos| over worlds 0..7 after 1, 10 and 100 env steps, each world
    from its initial state, its action held, against a CPU model at its point."""
    k = min(8, len(pts))
    cpu = []
    for i in range(k):
        env.set_params(**pts[i])
        data = mujoco.MjData(env.model)
        data.qpos[:], data.qvel[:], data.ctrl[:] = qpos[i], qvel[i], ctrl[i]
        traj = []
        for t in range(100):
            for _ in range(skip):
                mujoco.mj_step(env.model, data)
            if t + 1 in (1, 10, 100):
                traj.append(data.qpos.copy())
        cpu.append(traj)
    env.reset_params()
    # the warp worlds have taken one env step already (the compile step)
    out = []
    got = d.qpos.numpy()[:k]
    out.append(float(np.abs(got - np.array([c[0] for c in cpu])).max()))
    for t in range(1, 100):
        for _ in range(skip):
            mjw.step(m, d)
        if t + 1 in (10, 100):
            got = d.qpos.numpy()[:k]
            idx = 1 if t + 1 == 10 else 2
            out.append(float(np.abs(got - np.array([c[idx] for c in cpu])).max()))
    return tuple(out)


def cpu_rate(env, skip: int, seed: int, steps: int = 2000) -> float:
    data = mujoco.MjData(env.model)
    data.ctrl[:] = np.random.default_rng(seed).uniform(-1, 1, env.model.nu)
    start = time.perf_counter()
    for _ in range(steps):
        for _ in range(skip):
            mujoco.mj_step(env.model, data)
    return steps / (time.perf_counter() - start)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--device", default="cuda", help="warp device: cuda or cpu")
    parser.add_argument("--tasks", nargs="+", default=list(IDS), choices=list(IDS))
    parser.add_argument("--worlds", nargs="+", type=int, default=[32, 256, 1024, 4096, 8192])
    parser.add_argument("--steps", type=int, default=200, help="timed env steps")
    parser.add_argument("--uncertainty", default="3d")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--nconmax", type=int, default=32, help="contacts per world")
    parser.add_argument("--njmax", type=int, default=160, help="constraint rows per world")
    run(parser.parse_args())


if __name__ == "__main__":
    main()
