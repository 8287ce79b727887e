"""Gymnasium v4 against v5, task by task: what ``paper=True`` changed when it moved from the v4
envs (the original code's files before 2023-11-28) to the v5 envs (its files from then through
the paper's time, ``docs/differences.md``), and the paper's parameter writes against rrls's.

For each of the paper's six tasks: observation size, the env's reward/health constants that
differ, the model constants that differ (per-geom friction, masses, damping, gear, timestep),
the reward terms reported in ``info``, and the effect on a fixed policy's return: the same
open-loop action sequence (seeded uniform actions) from the same reset seeds, on the v4 env and
on the v5 env, and on rrls's robust env with ``worldfriction`` moved away from nominal under each
semantics (v5: every geom; paper: the original code's write, the floor only on Hopper and
Walker2d, every geom on HalfCheetah; both on the v5 env). Prints the tables in
docs/differences.md, with the versions they were measured on.

    python3 benchmarks/physics_differences.py [--episodes 3] [--steps 1000]
"""

from __future__ import annotations

import argparse
import warnings

import gymnasium as gym
import mujoco
import numpy as np

import rrls  # noqa: F401
from rrls.envs import ROBUST_ENVS
from rrls.envs.base import mujoco_warnings_to_python
from rrls.tasks import TASKS

PAPER = ("ant", "halfcheetah", "hopper", "humanoidstandup", "invertedpendulum", "walker")
MODEL_FIELDS = ("body_mass", "geom_friction", "dof_damping", "dof_armature", "actuator_gear")


def _returns(make, actions: np.ndarray, episodes: int) -> float:
    totals = []
    for seed in range(episodes):
        env = make()
        env.reset(seed=seed)
        total = 0.0
        for a in actions[seed]:
            _, r, term, trunc, _ = env.step(a)
            total += float(r)
            if term or trunc:
                break
        totals.append(total)
    return float(np.mean(totals))


def _constants(env) -> dict[str, object]:
    return {
        k: v
        for k, v in vars(env).items()
        if k.startswith("_")
        and not k.startswith("__")
        and isinstance(v, (int, float, tuple, bool))
        and k not in ("_np_random_seed", "_ezpickle_args", "_ezpickle_kwargs")
    }


def _model_diff(m4, m5) -> list[str]:
    out = []
    for field in MODEL_FIELDS:
        a, b = getattr(m4, field), getattr(m5, field)
        if a.shape != b.shape:
            out.append(f"{field} shape {a.shape} vs {b.shape}")
            continue
        rows = np.flatnonzero((a != b).reshape(len(a), -1).any(axis=1))
        obj = {"body": mujoco.mjtObj.mjOBJ_BODY, "geom": mujoco.mjtObj.mjOBJ_GEOM}.get(
            field.split("_")[0]
        )
        for i in rows:
            name = mujoco.mj_id2name(m4, obj, int(i)) if obj is not None else str(i)
            va, vb = np.ravel(a[i])[0], np.ravel(b[i])[0]
            out.append(f"{field}[{name}] {va:g} (v4) vs {vb:g} (v5)")
    if m4.opt.timestep != m5.opt.timestep:
        out.append(f"timestep {m4.opt.timestep} vs {m5.opt.timestep}")
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--episodes", type=int, default=3)
    parser.add_argument("--steps", type=int, default=1000)
    args = parser.parse_args()
    warnings.simplefilter("ignore")
    with mujoco_warnings_to_python():  # HalfCheetah's deprecated settotalmass: no log file
        run(args)


def run(args: argparse.Namespace) -> None:
    print(f"gymnasium {gym.__version__}, mujoco {mujoco.__version__}\n")
    rows = []
    for key in PAPER:
        task = TASKS[key]
        v4_id = task.v5_id.replace("-v5", "-v4")  # what paper=True built until 2026-11-27
        v4, v5 = gym.make(v4_id).unwrapped, gym.make(task.v5_id).unwrapped
        space = v5.action_space
        rng = np.random.default_rng(0)
        actions = rng.uniform(space.low, space.high, (args.episodes, args.steps, *space.shape))
        c4, c5 = _constants(v4), _constants(v5)
        consts = [f"{k} {c4.get(k)} (v4) vs {c5.get(k)} (v5)" for k in sorted({*c4, *c5})
                  if c4.get(k) != c5.get(k)]  # fmt: skip
        v4.reset(seed=0), v5.reset(seed=0)
        i4 = set(v4.step(actions[0, 0])[4]) - {"x_position"}
        i5 = set(v5.step(actions[0, 0])[4]) - {"x_position"}
        ret4 = _returns(lambda i=v4_id: gym.make(i), actions, args.episodes)
        ret5 = _returns(lambda t=task: gym.make(t.v5_id), actions, args.episodes)
        cls = ROBUST_ENVS[key]
        friction = {}
        if "worldfriction" in cls.param_names():
            for paper in (False, True):

                def make(paper=paper, cls=cls):
                    env = cls(paper=paper)
                    env.set_params(worldfriction=0.3)
                    return gym.wrappers.TimeLimit(env, 1000)

                friction[paper] = _returns(make, actions, args.episodes)
        rows.append((key, v4, v5, consts, _model_diff(v4.model, v5.model), i4, i5, ret4, ret5,
                     friction))  # fmt: skip
        print(f"## {key} ({v4_id} vs {task.v5_id})")
        print(f"- observation: {v4.observation_space.shape[0]} vs {v5.observation_space.shape[0]}")
        print(f"- info reward terms: v4 {sorted(i4)}; v5 {sorted(i5)}")
        print("- env constants: " + ("; ".join(consts) or "same"))
        print("- model constants: " + ("; ".join(_model_diff(v4.model, v5.model)) or "same"))
        print(f"- fixed open-loop policy, mean return: v4 {ret4:,.1f}, v5 {ret5:,.1f}")
        if friction:
            print(
                f"- same policy, worldfriction=0.3: v5 semantics (every geom) "
                f"{friction[False]:,.1f}, paper semantics (the original's write) "
                f"{friction[True]:,.1f}"
            )
        print()


if __name__ == "__main__":
    main()
