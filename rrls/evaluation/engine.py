"""The rollout engine: many (parameter point, seed) episodes in lockstep, on several processes.

Why this shape:

* **Exact.** Lockstep lanes (:mod:`rrls.evaluation.lanes`) change only *when* an episode is
  stepped, never its numbers; so results do not depend on the number of workers or the batch
  size.
* **Fast.** The policy runs once per step on all live lanes of a worker; workers are processes
  (one per core), each with its own envs.
* **Balanced.** The unit of work is one episode, not one chunk (:mod:`rrls.evaluation.scheduling`):
  equal contiguous shares, then work stealing, so no worker idles while episodes remain.
* **Nothing lost.** Episodes are saved in fixed chunks (:mod:`rrls.evaluation.chunks`); a
  re-run with the same arguments loads them instead of running them.
* **No orphans.** Workers die with the evaluation that started them (``rrls._proc``).
"""

from __future__ import annotations

import multiprocessing as mp
import os
import signal
import sys
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from threadpoolctl import threadpool_limits

from rrls._proc import cores, die_with_parent, release_stops, stops_held
from rrls._progress import progress_bar
from rrls.evaluation.chunks import CHUNK, chunk_path, load_chunk, remove_leftovers, save_chunk
from rrls.evaluation.lanes import LANES, Finished, Rollouts, make_rollout_envs, run_rows
from rrls.evaluation.scheduling import WorkPlan, plan_work, shared_bounds, steal_horizon, take_row

__all__ = ["default_workers", "run"]


def default_workers() -> int:
    """Every core this process may use."""
    return cores()


def run(
    spec: Rollouts,
    policy: Callable[[np.ndarray], Any],
    workers: int | None = None,
    lanes: int = LANES,
    chunk: int = CHUNK,
    chunk_dir: str | Path | None = None,
    progress: bool | None = None,
    fast: bool = True,
    threads: int = 1,
) -> dict[str, np.ndarray]:
    """All episodes of ``spec`` as columns; finished chunks are saved to/loaded from ``chunk_dir``.

    Chunks are fixed blocks of ``chunk`` consecutive rows: the unit of saving and resuming. Which
    worker runs which episode does not matter: every row's numbers depend only on its point,
    its seed and the policy. ``threads``: threads stepping each worker's lanes (1 by default:
    runs of a benchmark each take one core; more pays where cores outnumber workers).
    """
    n = spec.n_episodes
    cols = {
        "return": np.zeros(n),
        "length": np.zeros(n, dtype=np.int64),
        "terminated": np.zeros(n, dtype=bool),
        "diverged": np.zeros(n, dtype=bool),
    }
    n_chunks = -(-n // chunk)
    remaining = np.array([min(chunk, n - c * chunk) for c in range(n_chunks)])
    if chunk_dir is not None:
        chunk_dir = Path(chunk_dir)
        chunk_dir.mkdir(parents=True, exist_ok=True)
        remove_leftovers(chunk_dir)
        for c in range(n_chunks):
            path = chunk_path(chunk_dir, c)
            if path.exists() and load_chunk(path, cols, slice(c * chunk, c * chunk + remaining[c])):
                remaining[c] = 0
    todo = np.concatenate(
        [np.arange(c * chunk, c * chunk + remaining[c]) for c in range(n_chunks) if remaining[c]]
        or [np.zeros(0, dtype=np.int64)]
    )
    workers = default_workers() if workers is None else int(workers)
    plan = plan_work(len(todo), workers, lanes)
    lanes = plan.lanes

    if len(todo):
        make_rollout_envs(spec, lanes)  # built once here: forked workers inherit them
    bar = progress_bar(n, unit="episode", desc="evaluating", shown=progress, initial=n - len(todo))

    def on_finished(finished: Finished) -> None:
        for row, ret, length, term, div in finished:
            cols["return"][row], cols["length"][row] = ret, length
            cols["terminated"][row], cols["diverged"][row] = term, div
            c = row // chunk
            remaining[c] -= 1
            if remaining[c] == 0 and chunk_dir is not None:
                save_chunk(chunk_dir, c, cols, slice(c * chunk, min((c + 1) * chunk, n)))
        bar.update(len(finished))

    try:
        if len(todo) and plan.workers == 1:
            it = iter(todo.tolist())
            # one BLAS thread, as in the workers: a policy's small products gain nothing from
            # more, and their spinning threads slowed a 256-256 MLP ~10x on a busy machine
            with threadpool_limits(1, user_api="blas"):
                run_rows(
                    spec,
                    policy,
                    lambda live: next(it, -1),
                    on_finished,
                    lanes,
                    fast,
                    threads=threads,
                )
        elif len(todo):
            _run_processes(spec, policy, todo, plan, fast, threads, on_finished)
    finally:
        bar.close()
    return cols


def _run_processes(
    spec: Rollouts,
    policy: Callable,
    todo: np.ndarray,
    plan: WorkPlan,
    fast: bool,
    threads: int,
    on_finished: Callable[[Finished], None],
) -> None:
    import queue as queue_mod

    # fork shares the policy with the workers without pickling it (lambdas and closures work);
    # spawn (other platforms) pickles it.
    ctx = mp.get_context("fork" if "fork" in mp.get_all_start_methods() else "spawn")
    bounds = ctx.Array("q", shared_bounds(plan, spec.max_episode_steps))
    results = ctx.Queue()
    procs = [
        ctx.Process(
            target=_worker_main,
            args=(spec, policy, todo, bounds, w, results, plan.lanes, fast, threads, os.getpid()),
            daemon=True,
        )
        for w in range(plan.workers)
    ]
    running = plan.workers
    try:
        with warnings.catch_warnings(), stops_held():
            warnings.simplefilter("ignore", DeprecationWarning)  # fork with threads (3.12+)
            for proc in procs:
                proc.start()
        while running:
            try:
                msg = results.get(timeout=1.0)
            except queue_mod.Empty:
                dead = [p for p in procs if not p.is_alive() and p.exitcode not in (0, None)]
                if dead:
                    raise RuntimeError(
                        f"an evaluation worker died (exit code {dead[0].exitcode}); "
                        "finished chunks are saved — re-run to resume"
                    ) from None
                continue
            if msg is None:
                running -= 1
            elif isinstance(msg, _Failure):
                raise msg.err
            else:
                on_finished(msg)
    finally:
        started = [proc for proc in procs if proc.pid is not None]
        for proc in started:
            if proc.is_alive():
                proc.terminate()
        for proc in started:
            proc.join()
        results.close()


def _worker_main(
    spec: Rollouts,
    policy: Callable,
    rows: np.ndarray,
    bounds: Any,
    w: int,
    results: Any,
    lanes: int,
    fast: bool,
    threads: int,
    parent: int,
) -> None:
    """A worker process: take rows (own share, then stolen ones), send finished episodes back."""
    # a forked worker inherits the command's handlers, SIGTERM-as-Ctrl-C among them
    # (rrls.interrupts); its parent stops it with SIGTERM, which must end it where it stands
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    die_with_parent(parent)
    try:
        release_stops()  # held while it was forked: a Ctrl-C now goes to the parent as an error
        try:  # one BLAS thread per process: the processes already use every core
            from threadpoolctl import threadpool_limits

            threadpool_limits(1)
        except ImportError:  # pragma: no cover - threadpoolctl is a dependency
            pass
        if "torch" in sys.modules:
            sys.modules["torch"].set_num_threads(1)

        horizon = steal_horizon(spec.max_episode_steps)

        def next_row(live: int) -> int:
            with bounds.get_lock():
                i = take_row(bounds, w, live, horizon)
            return int(rows[i]) if i >= 0 else -1

        far = [True]  # as published: "no lane of mine frees within the horizon"

        def on_step(soon: int) -> None:
            if (soon > horizon) != far[0]:  # take_row only compares with the horizon
                far[0] = soon > horizon
                bounds[3 * w + 2] = soon

        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # MuJoCo model warnings: the parent reported them
            run_rows(spec, policy, next_row, results.put, lanes, fast, on_step, threads)
        results.put(None)
    except BaseException as err:  # noqa: BLE001 - forwarded to the parent, which re-raises
        results.put(_Failure(err))


class _Failure:
    """An exception from a worker, carried to the parent (re-raised there with its message)."""

    def __init__(self, err: BaseException) -> None:
        import traceback

        self.err = err if _picklable(err) else RuntimeError(f"{type(err).__name__}: {err}")
        self.trace = "".join(traceback.format_exception(err))


def _picklable(obj: Any) -> bool:
    import pickle

    try:
        pickle.dumps(obj)
    except Exception:  # noqa: BLE001
        return False
    return True
