"""The benchmark's pipeline: what one group of runs does, wherever it executes.

A group is runs that share algorithm, task and set and differ only in seed; its runs are trained
together by ``rrls.agents.loop.train_group`` (one stacked agent: on a GPU, many seeds at once;
each run's numbers are those it has alone). By default a group is one run on CPU and all the
seeds of a cell on CUDA (``pack``).

A run = train (``rrls.agents.train``, resumed from its checkpoint if one exists), then the final
mesh evaluation (resumable chunks under ``eval/``), then for RARL/NR-MDP the protagonist against
its own adversary (``dynamic.csv``), then ``result.json``: the marker of a finished run, written
last and atomically. Everything lives in the run's directory, so a killed driver loses nothing
finished and a re-run picks up where each run stopped. The backends (``backends``: a local
process pool or Ray) only decide where ``execute_recorded`` runs and report what it left.

Threads: every run is single-threaded (torch, BLAS, the evaluation's workers). Two runs with
two threads each on 2 cores took 118 s for what takes 38 s with one thread each.
"""

from __future__ import annotations

import math
import os
import time
import traceback
from collections.abc import Callable
from contextlib import ExitStack
from pathlib import Path
from typing import Any

from rrls import files, rundir
from rrls._proc import THREAD_ENV
from rrls.algorithms import plays_adversary
from rrls.benchmark.grid import Benchmark, RunKey
from rrls.benchmark.stages import run_dynamic, run_evaluation
from rrls.files import DirectoryLock, atomic_write_json, read_json
from rrls.schema import Schema, integer, number, string


def run_dir(root: Path, spec: Benchmark, key: RunKey) -> Path:
    return Path(root) / "runs" / key.name(spec.uncertainty)


def groups(
    keys: list[RunKey], pack: int, spec: Benchmark | None = None
) -> list[tuple[RunKey, ...]]:
    """``keys`` packed into groups of at most ``pack`` runs of one (algorithm, task) cell, the
    cells taken in turn (every cell's first group, then every cell's second...), so that a
    benchmark stopped part-way has every algorithm's first seeds (``pack=1``: ``keys``' order).
    With ``spec`` on the Warp twin, a task's groups of one turn whose runs can share a twin
    (``shares_twin``) are one group: its algorithms train on one twin step
    (``rrls.agents.shared``)."""
    cells: dict[tuple[str, str], list[RunKey]] = {}
    for key in keys:
        cells.setdefault((key.algo, key.task), []).append(key)
    chunks = [
        [tuple(members[i : i + pack]) for i in range(0, len(members), pack)]
        for members in cells.values()
    ]
    turns = [
        (turn, c[turn])
        for turn in range(max(map(len, chunks), default=0))
        for c in chunks
        if turn < len(c)
    ]
    out: list[list[RunKey]] = []
    shared: dict[tuple[int, str], list[RunKey]] = {}
    for turn, chunk in turns:
        if spec is None or not all(shares_twin(spec, key) for key in chunk):
            out.append(list(chunk))
        elif (turn, chunk[0].task) in shared:
            shared[turn, chunk[0].task].extend(chunk)
        else:
            out.append(shared.setdefault((turn, chunk[0].task), list(chunk)))
    return [tuple(group) for group in out]


def shares_twin(spec: Benchmark, key: RunKey) -> bool:
    """Whether ``key``'s run may share a twin step with other algorithms' runs of its task: it
    trains on the twin (its task has one), a built-in algorithm (device-resident), neither
    M2TD3's ``same_start`` (each episode begun on its CPU env) nor TC-RMDP's rate-limited game
    (its parameters move on the host)."""
    from rrls.algorithms import built_in

    hyper = spec.hyperparameters(key.algo)
    return (
        spec.simulator_for(key.task) == "warp"
        and key.algo in built_in()
        and not hyper.get("same_start")
        and hyper.get("rate_limit") is None
    )


def default_pack(spec: Benchmark, pack: int | None) -> int:
    """Runs per group: ``pack`` if given, else every seed of a cell on CUDA (the GPU updates
    them at once) and 1 on CPU (a process per run already uses every core)."""
    if pack is not None:
        return pack
    return len(spec.seeds) if spec.device.startswith("cuda") else 1


# --- one group (executes in a worker process or a Ray worker) ----------------------------------
def execute_run(root: str, spec_json: dict[str, Any], key: tuple[str, str, int]) -> dict[str, Any]:
    """Train, evaluate and (RARL/NR-MDP) play the adversary; returns ``result.json``'s content.

    Each stage is skipped when its output exists, and resumes from its own files otherwise.
    """
    return execute_group(root, spec_json, [key])[0]


def execute_group(
    root: str, spec_json: dict[str, Any], keys: list[tuple[str, str, int]], eval_workers: int = 1
) -> list[dict[str, Any]]:
    """``execute_run`` for runs of one cell (on the twin: of one task's cells), trained
    together; returns each ``result.json``.

    Runs already finished are skipped; the others are trained in one ``train_group`` call (a
    run whose training finished is left out; runs resumed at different steps are fine), then
    each is evaluated on its own (on ``eval_workers`` processes: the cores a GPU benchmark's
    few groups leave idle; the same rows whatever the count). A failing stage of one run writes
    its ``error.txt`` and the others go on; ``GroupFailed`` is raised at the end.
    """
    os.environ.update(THREAD_ENV)  # before numpy/torch load here (a no-op if already loaded)
    from threadpoolctl import threadpool_limits

    spec = Benchmark.from_json(spec_json)
    runs = [RunKey(*key) for key in keys]
    outs = [run_dir(Path(root), spec, run) for run in runs]
    results: dict[int, dict[str, Any]] = {}
    for i, out in enumerate(outs):
        if (out / rundir.RESULT).exists():
            results[i] = files.read_checked_json(out / rundir.RESULT)
    todo = [i for i in range(len(runs)) if i not in results]
    if not todo:
        return [results[i] for i in range(len(runs))]
    for i in todo:
        outs[i].mkdir(parents=True, exist_ok=True)
    with ExitStack() as stack:
        for i in todo:
            stack.enter_context(DirectoryLock(outs[i]))
        stack.enter_context(threadpool_limits(1))
        todo_runs, todo_outs = [runs[i] for i in todo], [outs[i] for i in todo]
        errors = _group_stages(spec, todo_runs, todo_outs, eval_workers)
        for i in todo:
            if i not in errors:
                results[i] = files.read_checked_json(outs[i] / rundir.RESULT)
    if errors:
        first = next(iter(errors.values()))
        lines = str(first).strip().splitlines() or [type(first).__name__]
        raise GroupFailed(f"{len(errors)} of {len(todo)} run(s) failed: {lines[-1]}") from first
    return [results[i] for i in range(len(runs))]


def _group_stages(
    spec: Benchmark, runs: list[RunKey], outs: list[Path], eval_workers: int = 1
) -> dict[int, BaseException]:
    """The stages of ``runs`` (training shared, the rest per run); returns each failed run's
    error (its traceback is in its ``error.txt``)."""

    start = time.time()
    errors: dict[int, BaseException] = {}
    todo = [i for i, out in enumerate(outs) if not (out / rundir.RESULT).exists()]
    # (a run finished by another process while this one waited to start is left alone)
    progress = {i: ProgressFile(outs[i] / rundir.PROGRESS, spec.steps) for i in todo}
    for i in todo:
        (outs[i] / rundir.ERROR).unlink(missing_ok=True)
    untrained = [i for i in todo if not (outs[i] / rundir.RUN_JSON).exists()]
    if untrained:
        for i in untrained:
            progress[i].write("train", 0)

        def train(part: list[int]) -> BaseException | None:
            try:
                parts = ([runs[i] for i in part], [outs[i] for i in part])
                _train(spec, *parts, [progress[i] for i in part])
            except Exception as err:  # noqa: BLE001 - written to error.txt, returned
                if len(part) == 1:  # a group's failure is retried run by run
                    _write_error(outs[part[0]])
                return err
            return None

        # together; if that fails, each alone (from its checkpoint), so that one bad run (a
        # corrupt checkpoint, say) fails alone, as it does unpacked
        if len(untrained) == 1 or train(untrained) is not None:
            for i in untrained:
                err = train([i])
                if err is not None:
                    errors[i] = err
    for i in todo:
        if i in errors:
            continue
        run, out = runs[i], outs[i]
        try:
            progress[i].write("evaluate", spec.steps)
            result = _evaluate(spec, run, out, eval_workers)
            if plays_adversary(run.algo):
                progress[i].write("dynamic", spec.steps)
                result.update(_dynamic(spec, run, out))
            # this execution's (a resumed run: since resuming; a group: since the group began)
            result["seconds"] = time.time() - start
            result["benchmark"] = spec.fingerprints()["benchmark"]
            files.write_checked_json(out / rundir.RESULT, result)
            progress[i].write("done", spec.steps)
            # The checkpoint only serves to resume training (its replay buffer is up to ~250 MB
            # at 5 M steps: 60 GB for the paper's grid); a finished run keeps its policies,
            # curves, logs.
            (out / rundir.CHECKPOINT).unlink(missing_ok=True)
        except Exception as err:  # noqa: BLE001 - written to error.txt, the others go on
            _write_error(out)
            errors[i] = err
    return errors


def _write_error(out: Path) -> None:
    """The current exception's traceback in ``out/error.txt`` (shown by the driver)."""
    out.mkdir(parents=True, exist_ok=True)
    (out / rundir.ERROR).write_text(traceback.format_exc())


def _train(
    spec: Benchmark, runs: list[RunKey], outs: list[Path], progress: list[ProgressFile]
) -> None:
    """Train ``runs`` (one cell, or on the twin one task's cells) together, resuming each from
    its checkpoint."""
    from rrls.agents import train_group

    configs = [spec.run_settings(run, out) for run, out in zip(runs, outs)]
    train_group(
        configs, resume=True, on_episode=lambda k, step, _: progress[k].write("train", step, False)
    )


def _evaluate(spec: Benchmark, run: RunKey, out: Path, workers: int = 1) -> dict[str, Any]:
    from rrls.evaluation import MLPPolicy

    policy = MLPPolicy.load(out / rundir.POLICY)
    trained = {"train_set": spec.train_set(run.algo), "steps": spec.steps}
    return run_evaluation(spec, run.algo, run.task, run.seed, policy, out, workers, False, trained)


def _dynamic(spec: Benchmark, run: RunKey, out: Path) -> dict[str, Any]:
    """The run's protagonist against its own final adversary, in the game it trained in (the
    adversary's metadata names it: RARL's, or NR-MDP's with its alpha)."""
    from rrls.evaluation import MLPPolicy

    policy = MLPPolicy.load(out / rundir.POLICY)
    adversary = MLPPolicy.load(out / rundir.ADVERSARY)
    meta = adversary.metadata
    game, alpha = meta.get("game", "adversarial"), meta.get("alpha")
    return run_dynamic(spec, run.task, policy, adversary, game, alpha, out)


#: the time constant of ``progress.json``'s steps/s (seconds)
SPS_SECONDS = 120.0


class ProgressFile:
    """``progress.json`` in the run directory: phase, step, steps/s (read by the driver).

    Steps/s is an exponential average over time (``SPS_SECONDS``), not over writes: a run
    writes at each episode's end, seconds apart on one task and a minute on another, and a
    shared machine's speed swings from minute to minute; the display's ETAs should not."""

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
                dt = now - self._prev[0]
                rate = (step - self._prev[1]) / dt
                weight = 1.0 - math.exp(-dt / SPS_SECONDS)  # this span's share of the average
                self._sps = rate if self._sps == 0 else self._sps + weight * (rate - self._sps)
            self._prev = (now, step)
        data = {
            "phase": phase,
            "step": step,
            "total": self.total,
            "sps": self._sps,
            "pid": os.getpid(),
        }
        atomic_write_json(self.path, data)


#: ``progress.json``: what the driver's display reads of a running run
PROGRESS_SCHEMA = Schema(
    {
        "phase": string(choices=("train", "evaluate", "dynamic", "done")),
        "step": integer(0),
        "total": integer(0),
        "sps": number(0),
        "pid": integer(0),
    }
)


def read_progress(path: Path) -> dict[str, Any] | None:
    """A run's progress, or None where there is none (yet) or it is not one: the display
    shows nothing for it rather than numbers it cannot trust."""
    try:
        return PROGRESS_SCHEMA.check(read_json(path / rundir.PROGRESS), "")
    except (OSError, ValueError):
        return None


class GroupFailed(RuntimeError):
    """Some runs of a group failed; each one's traceback is already in its ``error.txt``."""


def execute_recorded(
    root: str, spec_json: dict[str, Any], keys: list[tuple[str, str, int]], eval_workers: int = 1
) -> list[dict[str, Any]]:
    """``execute_group``, and a failure outside the runs' stages (a held lock, an interrupt)
    written to the ``error.txt`` of each run left unfinished."""
    try:
        return execute_group(root, spec_json, keys, eval_workers)
    except GroupFailed:
        raise
    except BaseException:
        spec = Benchmark.from_json(spec_json)
        for key in keys:
            out = run_dir(Path(root), spec, RunKey(*key))
            if not (out / rundir.RESULT).exists():
                _write_error(out)
        raise


Status = Callable[[RunKey, str, str], None]  # (run, "running" | "done" | "failed", detail)


def run_ok(root: Path, spec: Benchmark, key: RunKey, group_ok: bool) -> bool:
    """Whether ``key`` ended well: its group did, or it wrote no error (a failed group may
    still have finished some of its runs)."""
    return group_ok or not (run_dir(root, spec, key) / rundir.ERROR).exists()


def finish_run(
    root: Path, spec: Benchmark, key: RunKey, ok: bool, on_event: Status, detail: str = ""
) -> None:
    out = run_dir(root, spec, key)
    if ok and (out / rundir.RESULT).exists():
        on_event(key, "done", "")
        return
    error = out / rundir.ERROR
    text = error.read_text().strip() if error.exists() else detail or "the run's process died"
    on_event(key, "failed", text.splitlines()[-1] if text else "failed")
