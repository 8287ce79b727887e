"""The GPU runbook: what one lease of a GPU machine measures in a single command of at most ten
minutes, set-up included, keeping every figure it measured if the lease cuts it short.

On the GPU machine ``benchmarks/gpu_payload.py device`` starts it, once the wheels the machine
lacks have arrived in pieces small enough for the ``run`` calls. Here, ``python3
benchmarks/gpu_payload.py build`` then ``plan`` (it prints the calls for the tree as it is);
for a tree of at most 20 MiB they are two, back to back (the machine keeps files ~30 s):

    run(command="PYTHONUNBUFFERED=1 python3 benchmarks/gpu_payload.py device", timeout_s=120,
        carry=[".gpu/manifest.json", ".gpu/payload.part01"])  # starts the machine; piece 1 in
    run(command=<the same>, timeout_s=600,
        carry=[".gpu/manifest.json", ".gpu/payload.part02"])  # installs; the runbook -> $OUT

then ``$OUT/rows.jsonl`` and ``$OUT/rows.md`` come back, even from a call cut short
(docs/gpu.md has the sizes). By hand:

    python3 benchmarks/gpu_runbook.py OUT --deadline 540                           # the lease
    python3 benchmarks/gpu_runbook.py OUT --device cpu --simulator mujoco --tiny   # the dry run

Its rows, most wanted first (so a deadline cuts the least wanted):

1. ``machine``: Python, torch and whether it sees CUDA, the GPU, warp, mujoco-warp, MuJoCo;
   on ``--device cuda`` without CUDA it stops there (exit 2);
2. ``loop``: the device-resident training loop (``rrls train --simulator warp``, TD3) on Hopper
   at K = 1, 32, 128, 256 runs in one process;
3. ``baseline``: the paper's five baselines at K = 10 on Hopper, then on HalfCheetah; those the
   twin refuses when it runs (``rrls.twin.catalog.not_on_twin``: an adversary not wired to the
   twin) give a ``refused: <reason>`` row, in the twin's own words, without a process;
   after each task's, ``shared``: the five at K = 10 each on ONE twin
   (``benchmarks/twin_shared.py``: 50 runs, one twin step for all, ``rrls.agents.shared``);
4. ``loop`` on HalfCheetah at K = 1, 32, 128, 256;
5. ``estimate``: the paper's protocol (``--preset paper``, 10 seeds packed K = 10 per process)
   on one GPU, recomputed from these rows with ``rrls.benchmark.gpu_estimate``; each cell is
   marked ``measured``, ``extrapolated`` (a twin task not measured: the mean of Hopper's and
   HalfCheetah's rows) or ``stored`` (no twin path or no row: the stored H100 figures of
   ``rrls benchmark --dry-run --device cuda``), beside that stored estimate; with ``shared``
   rows, also the protocol as ``rrls benchmark --simulator warp`` packs it (a task's
   algorithms on one twin: ``shared_wall_h``, its tasks' rates measured or extrapolated).

A rate is the loop's own clock: ``charts/steps_per_second`` of run 0's episode ends gives the
time at each end, and the rate is taken between the first end after ``--window-after`` steps
(the warm-up and the first updates, which capture the CUDA graphs, are before it) and the last,
times K. Every row is printed and appended to ``OUT/rows.jsonl`` (flushed and synced) the moment
it exists, and ``OUT/rows.md`` is rewritten after it. Each step runs in its own process group
under a timeout, the smaller of ``--step-timeout`` and what ``--deadline`` leaves: one that
exceeds it is killed and written as ``timed out``, one that fails as ``failed: <last line>``,
and the next step runs; steps the deadline leaves under ``MIN_STEP_S`` for are ``skipped``.
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import platform
import signal
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
KS = (1, 32, 128, 256)  # the device-resident loop's sweep (TD3)
PACK = 10  # the baselines' K: the paper's 10 seeds in one process
TASKS = ("hopper", "halfcheetah")
MIN_STEP_S = 20.0  # a step with less time left than this is skipped, not started
#: the dry run: one sweep row, one baseline trained (DR) and a row for each the twin refuses
TINY = dict(ks=(1,), pack=2, tasks=("hopper",), algos=("dr",))
TINY.update(steps=60, starts=20, window_after=20)


@dataclass
class Step:
    """One row to measure: a process (``command``) or a refusal (``refused``, no process)."""

    kind: str  # "loop", "baseline" or "shared"
    algo: str
    task: str
    k: int
    command: list[str] | None = None
    runs: Path | None = None  # the run directories it writes (run 0's scalars give the rate)
    after: int = 0  # the rate's window starts at the first episode end after this step
    refused: str | None = None
    total: int = 0  # runs in the step (0: k): the shared step's algorithms x k


class Rows:
    """``rows.jsonl`` (one JSON object a line, appended, flushed and synced as each row is
    measured: a runbook killed mid-step keeps every earlier row) and ``rows.md``."""

    def __init__(self, out: Path) -> None:
        out.mkdir(parents=True, exist_ok=True)
        self.jsonl, self.md = out / "rows.jsonl", out / "rows.md"
        self.rows: list[dict[str, Any]] = []

    def add(self, row: dict[str, Any]) -> None:
        self.rows.append(row)
        with self.jsonl.open("a") as f:
            f.write(json.dumps(row) + "\n")
            f.flush()
            os.fsync(f.fileno())
        print(line(row), flush=True)
        self.md.write_text("# GPU runbook rows\n\n" + "".join(f"- {line(r)}\n" for r in self.rows))


def line(row: dict[str, Any]) -> str:
    """One row, readable."""
    if row["kind"] == "machine":
        return "machine: " + ", ".join(f"{k} {v}" for k, v in row.items() if k != "kind")
    if row["kind"] == "estimate" and "wall_h" in row:
        return (
            f"estimate ({row['protocol']}, K = {row['pack']}): {row['wall_h']:.1f} h on one GPU "
            f"from these rows (training {row['train_h']:.1f} h; cells {row['sources']}) against "
            f"{row['stored_wall_h']:.1f} h from the stored H100 figures"
            + (
                f"; a task's algorithms sharing each twin step: {row['shared_wall_h']:.1f} h"
                if "shared_wall_h" in row
                else ""
            )
        )
    what = f"{row['kind']} {row['algo']} {row['task']} K={row['k']}: {row['status']}"
    if row["status"] == "ok" and "env_steps_per_s" in row:
        what += (
            f", {row['env_steps_per_s']:,.0f} env steps/s ({row['per_run']:,.1f} per run, "
            f"steps {row['window'][0]}-{row['window'][1]})"
        )
    return what + (f" in {row['wall_s']:.0f} s" if "wall_s" in row else "")


def machine(device: str) -> dict[str, Any]:
    """What the machine has: a missing package or a torch without CUDA is said, not raised."""
    from importlib.metadata import PackageNotFoundError, version

    row: dict[str, Any] = {"kind": "machine", "python": platform.python_version()}
    row["cpus"] = os.cpu_count()
    try:
        import torch

        row["torch"] = torch.__version__
        row["cuda"] = bool(torch.cuda.is_available())
        if row["cuda"]:
            row["gpu"] = torch.cuda.get_device_name(0)
    except ImportError as err:
        row["torch"] = f"missing ({err})"
        row["cuda"] = False
    for name in ("warp-lang", "mujoco-warp", "mujoco", "gymnasium"):
        try:
            row[name] = version(name)
        except PackageNotFoundError:
            row[name] = "missing"
    row["device"] = device
    return row


def rate_from_scalars(path: Path, after: int) -> tuple[float, tuple[int, int]]:
    """Env steps/s of one run between its first episode end after step ``after`` and its last,
    from the loop's own ``charts/steps_per_second`` (steps since the start / seconds since the
    start, logged at each episode end). Fewer than two ends after ``after``: the whole run's."""
    with path.open(newline="") as f:
        ends = [
            (int(r["step"]), float(r["value"]))
            for r in csv.DictReader(f)
            if r["metric"] == "charts/steps_per_second" and float(r["value"]) > 0
        ]
    if not ends:
        raise ValueError(f"{path}: no episode ended, no rate")
    late = [(s, s / v) for s, v in ends if s > after]  # (step, seconds since the start)
    if len(late) < 2 or late[-1][1] <= late[0][1]:
        step, value = ends[-1]
        return value, (0, step)
    (s0, t0), (s1, t1) = late[0], late[-1]
    return (s1 - s0) / (t1 - t0), (s0, s1)


def run_step(step: Step, timeout: float) -> dict[str, Any]:
    """Run one step in its own process group; a timeout kills the whole group."""
    row: dict[str, Any] = {"kind": step.kind, "algo": step.algo, "task": step.task, "k": step.k}
    if step.refused is not None:
        return {**row, "status": f"refused: {step.refused}"}
    assert step.command is not None
    row["command"] = " ".join(step.command)
    start = time.perf_counter()
    proc = subprocess.Popen(
        step.command,
        cwd=ROOT,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
    )
    try:
        _, err = proc.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.communicate()
        return {**row, "status": f"timed out after {timeout:.0f} s", "wall_s": timeout}
    row["wall_s"] = time.perf_counter() - start
    if proc.returncode != 0:
        last = (err or "").strip().splitlines()[-1:] or [f"exit status {proc.returncode}"]
        return {**row, "status": f"failed: {last[0][:300]}"}
    if step.runs is not None:
        try:
            per_run, window = rate_from_scalars(step.runs / "seed0" / "scalars.csv", step.after)
        except (OSError, ValueError) as exc:
            return {**row, "status": f"failed: {exc}"}
        runs = step.total or step.k
        row.update(per_run=per_run, env_steps_per_s=per_run * runs, window=list(window))
        row["runs"] = runs
    return {**row, "status": "ok"}


def run_steps(steps: list[Step], rows: Rows, deadline: float, step_timeout: float) -> None:
    """Each step under the smaller of ``step_timeout`` and what is left before ``deadline``
    (a ``time.monotonic()`` instant); the rows as they come."""
    for step in steps:
        left = deadline - time.monotonic()
        if step.refused is None and left < MIN_STEP_S:
            head = {"kind": step.kind, "algo": step.algo, "task": step.task, "k": step.k}
            rows.add({**head, "status": f"skipped: {max(left, 0):.0f} s left before the deadline"})
            continue
        rows.add(run_step(step, min(step_timeout, left)))


def plan(args: argparse.Namespace, tmp: Path) -> list[Step]:
    """The steps, most wanted first: the TD3 sweep on the first task, the baselines on each
    task, then the sweep on the other tasks."""
    from rrls.algorithms import paper_five
    from rrls.twin.catalog import not_on_twin

    ks, pack, tasks = args.ks, args.pack, args.tasks
    algos = paper_five()
    if args.algos:  # the dry run: these, and those the twin refuses (rows without a process)
        algos = tuple(a for a in algos if a in args.algos or not_on_twin(a))

    def train(kind: str, algo: str, task: str, k: int) -> Step:
        why = not_on_twin(algo)
        if why is not None:
            return Step(kind, algo, task, k, refused=f"the Warp twin does not train {algo}: {why}")
        runs = tmp / f"{kind}-{algo}-{task}-{k}"
        command = [sys.executable, "-m", "rrls", "train", "--algo", algo, "--task", task]
        command += ["--uncertainty", "3d", "--seeds", f"0-{k - 1}", "--steps", str(args.steps)]
        command += ["--learning-starts", str(args.starts), "--eval-every", "0"]
        command += ["--checkpoint-every", str(10 * args.steps), "--device", args.device]
        command += ["--simulator", args.simulator, "--out", str(runs), "--overwrite"]
        return Step(kind, algo, task, k, command, runs, after=args.window_after)

    def shared(task: str) -> Step:
        runs = tmp / f"shared-{task}-{pack}"
        command = [sys.executable, str(ROOT / "benchmarks" / "twin_shared.py"), str(runs)]
        command += ["--task", task, "--k", str(pack), "--steps", str(args.steps)]
        command += ["--starts", str(args.starts), "--device", args.device]
        five = paper_five()
        total = len(five) * pack
        return Step(
            "shared", "+".join(five), task, pack, command, runs, args.window_after, total=total
        )

    steps = [train("loop", "td3", tasks[0], k) for k in ks]
    for task in tasks:
        steps += [train("baseline", algo, task, pack) for algo in algos]
        if args.simulator == "warp" and not args.algos:  # not in the CPU dry run's sizes
            steps.append(shared(task))
    for task in tasks[1:]:
        steps += [train("loop", "td3", task, k) for k in ks]
    return steps


def measured_rate(rows: list[dict[str, Any]]) -> tuple[Callable[..., Any], dict[str, str]]:
    """``gpu_estimate``'s rate from the rows, and where each cell's figure came from."""
    from rrls.benchmark.gpu_estimate import stored_rate
    from rrls.twin.catalog import TWIN_TASKS, not_on_twin

    ok = {
        (r["algo"], r["task"], r["k"]): r["env_steps_per_s"]
        for r in rows
        if r.get("status") == "ok" and "env_steps_per_s" in r
    }
    sources: dict[str, str] = {}

    def rate(algo: str, task: str, k: int) -> tuple[float, bool]:
        cell = f"{algo}/{task}"
        if (algo, task, k) in ok:
            sources[cell] = "measured"
            return ok[(algo, task, k)], True
        near = [v for (a, t, kk), v in ok.items() if a == algo and kk == k]
        if near and task in TWIN_TASKS and not_on_twin(algo) is None:
            sources[cell] = "extrapolated"
            return sum(near) / len(near), False
        sources[cell] = "stored"
        return stored_rate(algo, k)

    return rate, sources


def shared_rate(rows: list[dict[str, Any]]) -> Callable[[str, int], tuple[float, bool]] | None:
    """A task's shared-twin rate from the ``shared`` rows (another task's, or another run count:
    the per-run rate held, extrapolated), or None without one."""
    ok = [r for r in rows if r["kind"] == "shared" and r.get("status") == "ok"]
    if not ok:
        return None

    def rate(task: str, runs: int) -> tuple[float, bool]:
        mine = [r for r in ok if r["task"] == task] or ok
        per_run = sum(r["per_run"] for r in mine) / len(mine)
        exact = any(r["task"] == task and r["runs"] == runs for r in mine)
        return per_run * runs, exact

    return rate


def paper_estimate(rows: list[dict[str, Any]], pack: int = PACK) -> dict[str, Any]:
    """The paper's protocol on one GPU from the measured rows, beside the stored figures'."""
    from dataclasses import replace

    from rrls.benchmark.gpu_estimate import gpu_estimate
    from rrls.benchmark.grid import make_spec

    spec = make_spec("paper")
    rate, sources = measured_rate(rows)
    est, stored = gpu_estimate(spec, pack, rate=rate), gpu_estimate(spec, pack)
    counts = {s: list(sources.values()).count(s) for s in ("measured", "extrapolated", "stored")}
    shared = shared_rate(rows)
    extra = {}
    if shared is not None:
        warp = replace(spec, simulator="warp")
        together = gpu_estimate(warp, pack, rate=rate, shared=shared)
        extra = {
            "shared_wall_h": together["wall_s"] / 3600,
            "shared_measured": together["measured"],
        }
    return {
        "kind": "estimate",
        "protocol": "paper",
        "pack": pack,
        "wall_h": est["wall_s"] / 3600,
        "train_h": est["train_s"] / 3600,
        "eval_h": est["eval_s"] / 3600,
        "stored_wall_h": stored["wall_s"] / 3600,
        "sources": ", ".join(f"{n} {s}" for s, n in counts.items() if n),
        "cells": sources,
        **extra,
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", type=Path, metavar="OUT_DIR")
    parser.add_argument("--device", default="cuda", help="cuda (default) or cpu (the dry run)")
    parser.add_argument("--simulator", default="warp", help="warp (default) or mujoco")
    parser.add_argument("--tiny", action="store_true", help="the CPU dry run's sizes")
    parser.add_argument("--deadline", type=float, default=540.0, help="seconds for all steps")
    parser.add_argument("--step-timeout", type=float, default=240.0, help="seconds per step")
    parser.add_argument("--steps", type=int, default=2_000, help="env steps per run")
    parser.add_argument("--starts", type=int, default=500, help="random steps before learning")
    parser.add_argument("--window-after", type=int, default=1_000, help="the rate's window start")
    args = parser.parse_args(argv)
    sizes: dict[str, Any] = dict(ks=KS, pack=PACK, tasks=TASKS, algos=None)
    for name, value in {**sizes, **(TINY if args.tiny else {})}.items():
        setattr(args, name, value)
    deadline = time.monotonic() + args.deadline
    rows = Rows(args.out)
    found = machine(args.device)
    rows.add(found)
    if args.device.startswith("cuda") and not found["cuda"]:
        print("no CUDA device seen by torch: nothing measured", flush=True)
        return 2
    with tempfile.TemporaryDirectory(prefix="rrls-runbook-") as tmp:
        run_steps(plan(args, Path(tmp)), rows, deadline, args.step_timeout)
    try:
        rows.add(paper_estimate(rows.rows, args.pack))
    except (ImportError, KeyError, ValueError, ZeroDivisionError) as exc:  # the rows stand
        rows.add({"kind": "estimate", "algo": "-", "task": "-", "k": 0, "status": f"failed: {exc}"})
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
