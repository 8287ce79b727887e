"""Run a benchmark's grid: one process per run (local pool) or one Ray task per run.

A run = train (``rrls.agents.train``, resumed from its checkpoint if one exists), then the final
mesh evaluation (resumable chunks under ``eval/``), then for RARL/NR-MDP the protagonist against
its own adversary (``dynamic.csv``), then ``result.json``: the marker of a finished run, written
last and atomically. Everything lives in the run's directory, so a killed driver loses nothing
finished and a re-run picks up where each run stopped.

Threads: every run is single-threaded (torch, BLAS, the evaluation's workers). Two runs with
two threads each on 2 cores took 118 s for what takes 38 s with one thread each.
"""

from __future__ import annotations

import json
import os
import sys
import time
import traceback
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from rrls.experiments.spec import RunKey, Spec

THREAD_ENV = {
    "OMP_NUM_THREADS": "1",
    "MKL_NUM_THREADS": "1",
    "OPENBLAS_NUM_THREADS": "1",
    "NUMEXPR_NUM_THREADS": "1",
}
DYNAMIC_ALGOS = ("rarl", "nrmdp")


def run_dir(root: Path, spec: Spec, key: RunKey) -> Path:
    return Path(root) / "runs" / key.name(spec.uncertainty)


# --- one run (executes in a worker process or a Ray worker) ------------------------------------
def execute_run(root: str, spec_json: dict[str, Any], key: tuple[str, str, int]) -> dict[str, Any]:
    """Train, evaluate and (RARL/NR-MDP) play the adversary; returns ``result.json``'s content.

    Each stage is skipped when its output exists, and resumes from its own files otherwise.
    """
    os.environ.update(THREAD_ENV)  # before numpy/torch load here (a no-op if already loaded)
    from threadpoolctl import threadpool_limits

    spec, run = Spec.from_json(spec_json), RunKey(*key)
    out = run_dir(Path(root), spec, run)
    done = out / "result.json"
    if done.exists():
        return json.loads(done.read_text())
    out.mkdir(parents=True, exist_ok=True)
    with _exclusive(out), threadpool_limits(1):
        return _stages(spec, run, out, done)


def _stages(spec: Spec, run: RunKey, out: Path, done: Path) -> dict[str, Any]:
    from rrls._io import atomic_write_json

    if done.exists():  # finished by another process while this one waited to start
        return json.loads(done.read_text())
    (out / "error.txt").unlink(missing_ok=True)
    progress = _ProgressFile(out / "progress.json", spec.steps)
    start = time.time()
    if not (out / "run.json").exists():
        progress.write("train", 0)
        _train(spec, run, out, progress)
    progress.write("evaluate", spec.steps)
    result = _evaluate(spec, run, out)
    if run.algo in DYNAMIC_ALGOS:
        progress.write("dynamic", spec.steps)
        result.update(_dynamic(spec, out))
    result["seconds"] = time.time() - start  # this execution's (a resumed run: since resuming)
    atomic_write_json(done, result)
    progress.write("done", spec.steps)
    # The checkpoint only serves to resume training (its replay buffer is up to ~250 MB at
    # 5 M steps: 60 GB for the paper's grid); a finished run keeps its policies, curves, logs.
    (out / "checkpoint.pt").unlink(missing_ok=True)
    return result


@contextmanager
def _exclusive(out: Path) -> Iterator[None]:
    """Hold ``out/.lock`` while the run executes: a second driver on the same directory (or an
    orphan of a killed one) cannot run it twice at once."""
    try:
        import fcntl
    except ImportError:  # not POSIX: no lock
        yield
        return
    with open(out / ".lock", "w") as handle:
        try:
            fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            raise RuntimeError(f"{out} is being run by another process") from None
        try:
            yield
        finally:
            fcntl.flock(handle, fcntl.LOCK_UN)


def _train(spec: Spec, run: RunKey, out: Path, progress: _ProgressFile) -> None:
    from rrls.agents import TrainConfig, train

    config = TrainConfig(
        algo=run.algo,
        task=run.task,
        uncertainty=spec.train_set(run.algo),
        steps=spec.steps,
        eval_every=spec.eval_every,
        eval_mesh=spec.eval_mesh,
        eval_episodes=spec.eval_episodes,
        seed=run.seed,
        out=str(out),
        device=spec.device,
        checkpoint_every=spec.checkpoint_every,
        threads=1,
        progress=False,
        hyper=spec.hyperparameters(run.algo),
    )
    train(config, resume=True, on_episode=lambda step, _: progress.write("train", step, False))


def _evaluate(spec: Spec, run: RunKey, out: Path) -> dict[str, Any]:
    from rrls.evaluation import MLPPolicy, evaluate

    policy = MLPPolicy.load(out / "policy.npz")
    result = evaluate(
        policy,
        run.task,
        spec.uncertainty,
        nb_mesh_dim=spec.mesh,
        episodes=spec.episodes,
        seed=spec.eval_seed,
        workers=1,
        out_dir=out / "eval",
        progress=False,
    )
    meta = policy.metadata
    return {
        "algorithm": run.algo,
        "task": run.task,
        "uncertainty": spec.uncertainty,
        "train_set": spec.train_set(run.algo),
        "seed": run.seed,
        "steps": spec.steps,
        "worst_case": result.worst_case,
        "average_case": result.average_case,
        "versions": meta.get("versions", {}),
    }


def _dynamic(spec: Spec, out: Path) -> dict[str, Any]:
    from rrls._io import atomic_write_table
    from rrls.evaluation import evaluate_run_dynamic

    result = evaluate_run_dynamic(out, episodes=spec.dynamic_episodes, seed=spec.eval_seed)
    atomic_write_table(out / "dynamic.csv", result.episodes)
    return {"dynamic_mean": result.mean, "dynamic_std": result.std, "dynamic_env": result.env_id}


class _ProgressFile:
    """``progress.json`` in the run directory: phase, step, steps/s (read by the driver)."""

    def __init__(self, path: Path, total: int) -> None:
        self.path, self.total = path, total
        self._last = 0.0
        self._prev: tuple[float, int] | None = None  # (time, step) of the previous train write
        self._sps = 0.0

    def write(self, phase: str, step: int, force: bool = True) -> None:
        now = time.monotonic()
        if not force and now - self._last < 1.0:
            return
        self._last = now
        if phase == "train" and step > 0:
            # smoothed rate between writes (start-up and imports do not count)
            if self._prev is not None and step > self._prev[1] and now > self._prev[0]:
                rate = (step - self._prev[1]) / (now - self._prev[0])
                self._sps = rate if self._sps == 0 else 0.7 * self._sps + 0.3 * rate
            self._prev = (now, step)
        data = {
            "phase": phase,
            "step": step,
            "total": self.total,
            "sps": self._sps,
            "pid": os.getpid(),
        }
        tmp = self.path.with_suffix(".tmp")
        tmp.write_text(json.dumps(data))
        os.replace(tmp, self.path)


def read_progress(path: Path) -> dict[str, Any] | None:
    try:
        return json.loads((path / "progress.json").read_text())
    except (OSError, ValueError):
        return None


# --- local backend: one spawned process per run ------------------------------------------------
def _process_main(root: str, spec_json: dict[str, Any], key: tuple[str, str, int]) -> None:
    """Entry point of a run's process: dies with the driver, writes error.txt on failure."""
    _die_with_parent()
    try:
        execute_run(root, spec_json, key)
    except BaseException:
        spec = Spec.from_json(spec_json)
        out = run_dir(Path(root), spec, RunKey(*key))
        out.mkdir(parents=True, exist_ok=True)
        (out / "error.txt").write_text(traceback.format_exc())
        sys.exit(1)


def _die_with_parent() -> None:
    """Exit when the driver goes away (killed included): no orphan keeps training."""
    parent = os.getppid()
    if sys.platform.startswith("linux"):
        try:
            import ctypes
            import signal

            libc = ctypes.CDLL("libc.so.6", use_errno=True)
            libc.prctl(1, signal.SIGKILL)  # PR_SET_PDEATHSIG
        except OSError:
            pass
    import threading

    def watch() -> None:
        while os.getppid() == parent:
            time.sleep(1.0)
        os._exit(1)

    threading.Thread(target=watch, daemon=True).start()
    if os.getppid() != parent:
        os._exit(1)


@contextmanager
def single_thread_env() -> Iterator[None]:
    """Children spawned inside inherit one-thread BLAS/OpenMP settings (restored after)."""
    saved = {k: os.environ.get(k) for k in THREAD_ENV}
    os.environ.update(THREAD_ENV)
    try:
        yield
    finally:
        for k, v in saved.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


Status = Callable[[RunKey, str, str], None]  # (run, "running" | "done" | "failed", detail)


def run_local(
    root: Path, spec: Spec, keys: list[RunKey], jobs: int, on_event: Status, tick: Callable
) -> None:
    """At most ``jobs`` run processes at a time; ``tick()`` refreshes the display (~2/s)."""
    import multiprocessing as mp

    ctx = mp.get_context("spawn")
    pending, running = list(keys), {}
    spec_json = spec.to_json()
    with single_thread_env():
        try:
            while pending or running:
                while pending and len(running) < jobs:
                    key = pending.pop(0)
                    proc = ctx.Process(
                        target=_process_main,
                        args=(str(root), spec_json, (key.algo, key.task, key.seed)),
                        name=f"rrls-run-{key.name(spec.uncertainty)}",
                    )
                    proc.start()
                    running[key] = proc
                    on_event(key, "running", "")
                for key, proc in list(running.items()):
                    if proc.is_alive():
                        continue
                    proc.join()
                    del running[key]
                    _finish(root, spec, key, proc.exitcode == 0, on_event)
                tick()
                time.sleep(0.5)
        finally:
            for proc in running.values():
                proc.terminate()
            for proc in running.values():
                proc.join(10)
                if proc.is_alive():
                    proc.kill()
                    proc.join()


def _finish(
    root: Path, spec: Spec, key: RunKey, ok: bool, on_event: Status, detail: str = ""
) -> None:
    out = run_dir(root, spec, key)
    if ok and (out / "result.json").exists():
        on_event(key, "done", "")
        return
    error = out / "error.txt"
    text = error.read_text().strip() if error.exists() else detail or "the run's process died"
    on_event(key, "failed", text.splitlines()[-1] if text else "failed")


# --- Ray backend: the same function as Ray tasks ----------------------------------------------
def run_ray(
    root: Path,
    spec: Spec,
    keys: list[RunKey],
    jobs: int | None,
    address: str | None,
    on_event: Status,
    tick: Callable,
) -> None:
    """One Ray task per run (one CPU; a quarter GPU with ``device="cuda"``). Connects to
    ``address`` (or ``RAY_ADDRESS``), else to the instance this process already started, else
    starts a local one. The run directories must be on a filesystem every node sees."""
    import ray

    started = False
    if not ray.is_initialized():
        ray.init(address=address or os.environ.get("RAY_ADDRESS"), include_dashboard=False)
        started = True
    gpus = 0.25 if spec.device.startswith("cuda") else 0
    task = ray.remote(num_cpus=1, num_gpus=gpus, max_retries=0)(_ray_run)
    spec_json = spec.to_json()
    limit = jobs or len(keys)
    pending, inflight = list(keys), {}
    try:
        while pending or inflight:
            while pending and len(inflight) < limit:
                key = pending.pop(0)
                ref = task.remote(str(root), spec_json, (key.algo, key.task, key.seed))
                inflight[ref] = key
                on_event(key, "running", "")
            ready, _ = ray.wait(list(inflight), num_returns=1, timeout=0.5)
            for ref in ready:
                key = inflight.pop(ref)
                try:
                    ray.get(ref)
                    ok, detail = True, ""
                except Exception as err:  # the task's traceback is also in error.txt
                    ok, detail = False, (str(err).strip().splitlines() or ["failed"])[-1]
                _finish(root, spec, key, ok, on_event, detail)
            tick()
    finally:
        for ref in inflight:
            ray.cancel(ref, force=True)
        if started:
            ray.shutdown()


def _ray_run(root: str, spec_json: dict[str, Any], key: tuple[str, str, int]) -> dict[str, Any]:
    try:
        return execute_run(root, spec_json, key)
    except BaseException:
        out = run_dir(Path(root), Spec.from_json(spec_json), RunKey(*key))
        out.mkdir(parents=True, exist_ok=True)
        (out / "error.txt").write_text(traceback.format_exc())
        raise
