"""Where a benchmark's groups execute: a local pool of spawned processes, or Ray tasks.

Both run the same function (``pipeline.execute_recorded``) on the same run directories and
report each run through ``pipeline.finish_run``: the numbers do not depend on the backend.
"""

from __future__ import annotations

import os
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from rrls._proc import die_with_parent, single_thread_env
from rrls.experiments.pipeline import Status, execute_recorded, finish_run, groups, run_ok
from rrls.experiments.spec import RunKey, Spec


# --- local backend: one spawned process per group ----------------------------------------------
def _group_main(root: str, spec_json: dict[str, Any], keys: list[tuple[str, str, int]]) -> None:
    """Entry point of a group's process: dies with the driver, writes error.txt on failure.
    Ctrl-C is the driver's to handle (it stops the groups and says how to resume): a group
    ignores SIGINT, so that it is not torn down half-way through its own cleanup."""
    import signal

    signal.signal(signal.SIGINT, signal.SIG_IGN)
    # the driver stops a group with SIGTERM: exit through Python, so that multiprocessing's
    # finalizers release the group's semaphores (no "leaked semaphore" warning at shutdown)
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(143))
    die_with_parent()
    try:
        execute_recorded(root, spec_json, keys)
    except BaseException:  # noqa: BLE001 - recorded in error.txt; the worker's exit says it
        sys.exit(1)


def run_local(
    root: Path,
    spec: Spec,
    keys: list[RunKey],
    jobs: int,
    on_event: Status,
    tick: Callable,
    pack: int = 1,
) -> None:
    """At most ``jobs`` group processes at a time (``groups(keys, pack)``); ``tick()``
    refreshes the display (~2/s)."""
    import multiprocessing as mp

    ctx = mp.get_context("spawn")
    pending, running = groups(keys, pack), {}
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
                        args=(str(root), spec_json, [(k.algo, k.task, k.seed) for k in group]),
                        name=f"rrls-run-{name}",
                    )
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
                proc.terminate()
            for proc in running.values():
                proc.join(10)
                if proc.is_alive():
                    proc.kill()
                    proc.join()


# --- Ray backend: the same function as Ray tasks ----------------------------------------------
def run_ray(
    root: Path,
    spec: Spec,
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
    filesystem every node sees."""
    import ray

    started = False
    if not ray.is_initialized():
        ray.init(address=address or os.environ.get("RAY_ADDRESS"), include_dashboard=False)
        started = True
    gpus = 0.25 if spec.device.startswith("cuda") else 0
    task = ray.remote(num_cpus=1, num_gpus=gpus, max_retries=0)(_ray_run)
    spec_json = spec.to_json()
    pending, inflight = groups(keys, pack), {}
    limit = jobs or len(pending)
    try:
        while pending or inflight:
            while pending and len(inflight) < limit:
                group = pending.pop(0)
                ref = task.remote(str(root), spec_json, [(k.algo, k.task, k.seed) for k in group])
                inflight[ref] = group
                for key in group:
                    on_event(key, "running", "")
            ready, _ = ray.wait(list(inflight), num_returns=1, timeout=0.5)
            for ref in ready:
                group = inflight.pop(ref)
                try:
                    ray.get(ref)
                    ok, detail = True, ""
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


def _ray_run(
    root: str, spec_json: dict[str, Any], keys: list[tuple[str, str, int]]
) -> list[dict[str, Any]]:
    return execute_recorded(root, spec_json, keys)
