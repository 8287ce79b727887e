"""Where a benchmark's groups execute: a local pool of spawned processes, or Ray tasks.

Both run the same function (``pipeline.execute_recorded``) on the same run directories and
report each run through ``pipeline.finish_run``: the numbers do not depend on the backend. On Ray,
a group whose node dies is submitted again and resumes from its runs' checkpoints (``run_ray``).
"""

from __future__ import annotations

import os
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from rrls._proc import die_with_parent, release_stops, single_thread_env, stops_held
from rrls.benchmark.grid import Benchmark, RunKey
from rrls.benchmark.pipeline import (
    Status,
    execute_recorded,
    finish_run,
    groups,
    run_dir,
    run_ok,
)
from rrls.files import DirectoryLock

# --- local backend: one spawned process per group ----------------------------------------------
#: how long a stopped group may take to checkpoint its runs (a 1 M-step replay buffer is ~80 MB
#: written and sealed) before it is killed; a second Ctrl-C does not wait
STOP_WAIT_S = 120.0


def _group_main(
    root: str, spec_json: dict[str, Any], keys: list[tuple[str, str, int]], eval_workers: int = 1
) -> None:
    """Entry point of a group's process: dies with the driver, writes error.txt on failure.
    Ctrl-C is the driver's to handle (it stops the groups and says how to resume): a group
    ignores SIGINT, so that it is not torn down half-way through its own cleanup."""
    import signal

    from rrls.interrupts import term_as_ctrl_c

    signal.signal(signal.SIGINT, signal.SIG_IGN)
    # the driver stops a group with SIGTERM, taken as Ctrl-C: a run in training finishes its
    # step and checkpoints it (nothing trained is lost), anything else stops at once; either
    # way the process exits through Python, so multiprocessing's finalizers release its
    # semaphores (no "leaked semaphore" warning at shutdown)
    term_as_ctrl_c()
    die_with_parent()
    try:
        release_stops()  # held since the driver started it (``stops_held``): its handlers are set
        execute_recorded(root, spec_json, keys, eval_workers)
    except BaseException:  # noqa: BLE001 - recorded in error.txt; the worker's exit says it
        sys.exit(1)


def run_local(
    root: Path,
    spec: Benchmark,
    keys: list[RunKey],
    jobs: int,
    on_event: Status,
    tick: Callable,
    pack: int = 1,
) -> None:
    """At most ``jobs`` group processes at a time (``groups(keys, pack)``); ``tick()``
    refreshes the display (~2/s). Packed groups fewer than the cores (a GPU benchmark's groups
    of many runs): each evaluates its runs on its share of the cores (``eval_workers``)."""
    import multiprocessing as mp

    ctx = mp.get_context("spawn")
    pending, running = groups(keys, pack, spec), {}
    packed = any(len(group) > 1 for group in pending)  # a run alone: one process, as ever
    eval_workers = eval_share(len(pending), jobs) if packed else 1
    spec_json = spec.to_json()
    with single_thread_env():
        try:
            while pending or running:
                while pending and len(running) < jobs:
                    group = pending.pop(0)
                    name = group[0].name(spec.uncertainty)
                    if len(group) > 1:
                        name += "-" + "-".join(str(key.seed) for key in group[1:])
                    proc = ctx.Process(
                        target=_group_main,
                        args=(
                            str(root),
                            spec_json,
                            [(k.algo, k.task, k.seed) for k in group],
                            eval_workers,
                        ),
                        name=f"rrls-run-{name}",
                    )
                    with stops_held():  # a Ctrl-C while it starts: no traceback from it
                        proc.start()
                        running[group] = proc
                    for key in group:
                        on_event(key, "running", "")
                for group, proc in list(running.items()):
                    if proc.is_alive():
                        continue
                    proc.join()
                    del running[group]
                    for key in group:
                        finish_run(
                            root, spec, key, run_ok(root, spec, key, proc.exitcode == 0), on_event
                        )
                tick()
                time.sleep(0.5)
        finally:
            for proc in running.values():
                proc.terminate()  # a run in training checkpoints the step it is in first
            for proc in running.values():
                proc.join(STOP_WAIT_S)
                if proc.is_alive():
                    proc.kill()
                    proc.join()


def eval_share(groups: int, jobs: int) -> int:
    """Evaluation processes per group: the machine's cores shared among the groups that run at
    once (1 when there are as many groups as jobs: a CPU benchmark's run per core)."""
    from rrls._proc import cores

    return max(1, cores() // max(1, min(groups, jobs)))


# --- Ray backend: the same function as Ray tasks ----------------------------------------------
#: how many more times a group is submitted when its node or its worker process dies under it
NODE_LOSS_RETRIES = 3
#: how long a resubmitted group waits for its run directories' locks: the lost node's process
#: may still hold them (a node cut off from the cluster runs on until it learns so; an NFS server
#: frees a dead client's locks once its lease runs out, 90 s by default)
LOCK_WAIT_S = 300.0


def run_ray(
    root: Path,
    spec: Benchmark,
    keys: list[RunKey],
    jobs: int | None,
    address: str | None,
    on_event: Status,
    tick: Callable,
    pack: int = 1,
) -> None:
    """One Ray task per group of ``groups(keys, pack)`` (one CPU; a quarter GPU with
    ``device="cuda"``). Connects to ``address`` (or ``RAY_ADDRESS``), else to the instance this
    process already started, else starts a local one. The run directories must be on a
    filesystem every node sees.

    A group whose node dies (or whose worker process dies: Ray's ``NodeDiedError``,
    ``WorkerCrashedError``, or its result lost with its node) is submitted again, ahead of the
    groups not yet started, up to ``NODE_LOSS_RETRIES`` times: it resumes from its runs'
    checkpoints on a node that is still up, once the lost process's locks on its run
    directories are free (``LOCK_WAIT_S``). An exception raised by a run is not retried: it is
    in the run's ``error.txt``.
    """
    import ray
    import ray.exceptions

    # (Ray before NodeDiedError reports a node's death as its worker's)
    names = ("NodeDiedError", "WorkerCrashedError", "ObjectLostError")
    lost = tuple(getattr(ray.exceptions, name) for name in names if hasattr(ray.exceptions, name))
    started = False
    if not ray.is_initialized():
        ray.init(address=address or os.environ.get("RAY_ADDRESS"), include_dashboard=False)
        started = True
    gpus = 0.25 if spec.device.startswith("cuda") else 0
    task = ray.remote(num_cpus=1, num_gpus=gpus, max_retries=0)(_ray_run)
    spec_json = spec.to_json()
    pending = [(group, 0) for group in groups(keys, pack, spec)]  # (group, times lost so far)
    inflight: dict[Any, tuple[tuple[RunKey, ...], int]] = {}
    limit = jobs or len(pending)
    try:
        while pending or inflight:
            while pending and len(inflight) < limit:
                group, lost_before = pending.pop(0)
                runs = [(k.algo, k.task, k.seed) for k in group]
                wait = LOCK_WAIT_S if lost_before else 0.0
                inflight[task.remote(str(root), spec_json, runs, wait)] = (group, lost_before)
                if not lost_before:
                    for key in group:
                        on_event(key, "running", "")
            ready, _ = ray.wait(list(inflight), num_returns=1, timeout=0.5)
            for ref in ready:
                group, lost_before = inflight.pop(ref)
                try:
                    ray.get(ref)
                    ok, detail = True, ""
                except lost as err:
                    which = ", ".join(key.name(spec.uncertainty) for key in group)
                    what = "node" if type(err).__name__ == "NodeDiedError" else "worker process"
                    if lost_before < NODE_LOSS_RETRIES:
                        pending.insert(0, (group, lost_before + 1))
                        print(
                            f"{which}: its Ray {what} died ({type(err).__name__}); submitted "
                            f"again ({lost_before + 1} of {NODE_LOSS_RETRIES}), it resumes from "
                            "its checkpoint",
                            file=sys.stderr,
                            flush=True,
                        )
                        continue
                    ok = False
                    detail = (
                        f"its Ray {what} died {lost_before + 1} times ({type(err).__name__}); "
                        "re-run the same command to resume it"
                    )
                except Exception as err:  # noqa: BLE001 - its traceback is in error.txt
                    ok, detail = False, (str(err).strip().splitlines() or ["failed"])[-1]
                for key in group:
                    finish_run(root, spec, key, run_ok(root, spec, key, ok), on_event, detail)
            tick()
    finally:
        for ref in inflight:
            ray.cancel(ref, force=True)
        if started:
            ray.shutdown()


def wait_for_locks(dirs: list[Path], seconds: float, poll: float = 0.5) -> bool:
    """Wait until no other process holds the lock of any of ``dirs`` (``DirectoryLock``), for at
    most ``seconds`` in all; whether they all came free. A directory not yet made is free."""
    deadline = time.monotonic() + seconds
    for directory in dirs:
        while directory.is_dir():
            try:
                with DirectoryLock(directory):
                    break
            except FileExistsError:
                if time.monotonic() >= deadline:
                    return False
                time.sleep(poll)
    return True


def _ray_run(
    root: str, spec_json: dict[str, Any], keys: list[tuple[str, str, int]], lock_wait: float = 0.0
) -> list[dict[str, Any]]:
    """``execute_recorded`` in a Ray worker; ``lock_wait`` > 0 (a group submitted again after
    its node died): first wait that long at most for its run directories' locks."""
    if lock_wait > 0:
        spec = Benchmark.from_json(spec_json)
        wait_for_locks([run_dir(Path(root), spec, RunKey(*key)) for key in keys], lock_wait)
    return execute_recorded(root, spec_json, keys)
