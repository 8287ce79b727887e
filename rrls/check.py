"""``rrls check``: build every task, run short random episodes at the nominal point and at the
corners of each uncertainty set, and print a table. A smoke test of the whole physics stack."""

from __future__ import annotations

import itertools
import time
from dataclasses import dataclass
from typing import Any

import numpy as np


@dataclass
class CheckRow:
    task: str
    uncertainty: str
    point: str
    steps: int
    ret: float
    ok: bool
    note: str = ""


def _episode(env, steps: int, seed: int, options: dict[str, float] | None) -> tuple[int, float]:
    rng = np.random.default_rng(seed)
    space = env.action_space
    env.reset(seed=seed, options=options)
    total, n = 0.0, 0
    for n in range(1, steps + 1):
        action = rng.uniform(space.low, space.high).astype(space.dtype)
        obs, reward, terminated, truncated, _ = env.step(action)
        if not np.all(np.isfinite(obs)) or not np.isfinite(reward):
            raise FloatingPointError(f"non-finite observation or reward at step {n}")
        total += float(reward)
        if terminated or truncated:
            break
    return n, total


def run_check(tasks: list[str] | None = None, steps: int = 100, seed: int = 0) -> list[CheckRow]:
    """Rows of the check table (one per task x set x point)."""
    from rrls.envs import resolve
    from rrls.tasks import TASKS, get_task

    if isinstance(steps, bool) or not isinstance(steps, int) or steps < 1:
        raise ValueError(f"steps must be an integer >= 1, got {steps!r}")
    rows: list[CheckRow] = []
    for key in [get_task(t).key for t in tasks] if tasks else list(TASKS):
        envs: dict[type, Any] = {}  # one env per family, reset between points
        for name in ("nominal", *TASKS[key].sets):
            resolved = resolve(key, name)
            box = resolved.box
            if resolved.env_class not in envs:
                envs[resolved.env_class] = resolved.make_env()
            env = envs[resolved.env_class]
            for corner in itertools.product(*zip(box.low, box.high)):
                label = ",".join(f"{v:g}" for v in corner) or "nominal"
                params = box.to_dict(corner) or None
                env.reset_params()
                try:
                    n, ret = _episode(env, steps, seed, params)
                    rows.append(CheckRow(key, name, label, n, ret, True))
                except Exception as exc:  # noqa: BLE001 - report, keep checking the rest
                    rows.append(CheckRow(key, name, label, 0, float("nan"), False, repr(exc)))
    return rows


def format_table(rows: list[CheckRow]) -> str:
    head = ("task", "set", "point", "steps", "return", "status")
    body = [
        (r.task, r.uncertainty, r.point, str(r.steps), f"{r.ret:.2f}", "ok" if r.ok else r.note)
        for r in rows
    ]
    widths = [max(len(x) for x in col) for col in zip(head, *body)]
    line = "  ".join(f"{{:<{w}}}" for w in widths)
    out = [line.format(*head), line.format(*("-" * w for w in widths))]
    out += [line.format(*b) for b in body]
    return "\n".join(out)


def main(tasks: list[str] | None, steps: int, seed: int) -> int:
    start = time.perf_counter()
    rows = run_check(tasks, steps, seed)
    print(format_table(rows))
    bad = sum(not r.ok for r in rows)
    took = time.perf_counter() - start
    print(f"\n{len(rows) - bad} ok, {bad} failed ({len(rows)} episodes, {took:.1f} s)")
    return 1 if bad else 0
