"""``benchmark()``: check the spec against the directory, run what is not finished, show progress,
then rebuild the result store and the report from the run directories."""

from __future__ import annotations

import statistics
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any, TextIO

from rrls import rundir
from rrls.benchmark.backends import run_local, run_ray
from rrls.benchmark.benchfile import reconcile
from rrls.benchmark.cpu_estimate import (
    estimate,
    format_duration,
    run_seconds,
    schedule,
    train_rate,
)
from rrls.benchmark.grid import Benchmark, RunKey
from rrls.benchmark.pipeline import default_pack, groups, read_progress, run_dir


class Display:
    """One overall bar plus a live table of the running runs (steps, steps/s, ETA) on a
    terminal; elsewhere (cluster logs) one plain line every ``interval`` seconds and one per
    finished or failed run."""

    def __init__(
        self,
        root: Path,
        spec: Benchmark,
        keys: list[RunKey],
        done_before: int,
        slots: int,
        stream: TextIO | None = None,
        interval: float = 60.0,
    ) -> None:
        self.root, self.spec = root, spec
        self.stream = stream or sys.stderr
        self.tty = bool(getattr(self.stream, "isatty", lambda: False)())
        self.state = {k: "pending" for k in keys}
        self.total = len(keys) + done_before
        self.done_before = done_before
        self.started: dict[RunKey, float] = {}
        self.durations: list[float] = []
        self.failures: dict[RunKey, str] = {}
        self.interval, self._last_line = interval, time.monotonic()
        self.t0 = time.monotonic()
        self.slots = max(1, min(slots, len(keys) or 1))
        self._trained_before = trained_steps(root, spec, keys)  # resumed runs' steps
        self._bar: Any = None
        self._rows: list[Any] = []
        if self.tty:
            from tqdm.auto import tqdm

            from rrls._progress import terminal_shape

            try:  # a real terminal of size 0x0 would hide the bars (an in-memory one has none)
                shape = terminal_shape(self.stream) if self.stream.fileno() >= 0 else {}
            except (AttributeError, ValueError, OSError):
                shape = {}
            self._bar = tqdm(
                total=self.total,
                initial=done_before,
                unit="run",
                file=self.stream,
                position=0,
                **shape,
            )
            self._rows = [
                tqdm(bar_format="{desc}", file=self.stream, position=i + 1, leave=False, **shape)
                for i in range(self.slots)
            ]

    def counts(self) -> dict[str, int]:
        out = {"pending": 0, "running": 0, "done": self.done_before, "failed": 0}
        for s in self.state.values():
            out[s] += 1
        return out

    def event(self, key: RunKey, state: str, detail: str) -> None:
        self.state[key] = state
        name = key.name(self.spec.uncertainty)
        if state == "running":
            self.started[key] = time.monotonic()
            return
        seconds = time.monotonic() - self.started.get(key, time.monotonic())
        if state == "done":
            self.durations.append(seconds)
            line = f"done   {name} ({format_duration(seconds)})"
        else:
            self.failures[key] = detail
            line = f"FAILED {name}: {detail} (see {run_dir(self.root, self.spec, key)}/error.txt)"
        if self._bar is not None:
            self._bar.update(1)
            self._bar.write(line, file=self.stream)
        else:
            print(line, file=self.stream, flush=True)
        self.tick()

    def _row(self, key: RunKey) -> str:
        name = key.name(self.spec.uncertainty)
        info = read_progress(run_dir(self.root, self.spec, key)) or {}
        phase, step, total = info.get("phase", "starting"), info.get("step", 0), info.get("total")
        sps = info.get("sps") or 0.0
        if phase == "train" and total:
            eta = f"ETA {format_duration((total - step) / sps)}" if sps > 0 else "ETA ?"
            return f"{name:<40} train {step:>9,}/{total:,}  {sps:6.0f} steps/s  {eta}"
        return f"{name:<40} {phase}"

    def eta(self) -> str:
        """The time left: the estimate of the runs not finished (each from the step it has
        reached), their training at the speed the running runs show against their estimated
        rates (this machine, its load), queued on this benchmark's slots; before any run
        shows a speed, the mean of the runs finished here, else "?"."""
        running = [k for k, s in self.state.items() if s == "running"]
        pending = [k for k, s in self.state.items() if s == "pending"]
        speeds, trained = [], dict(self._trained_before)
        for key in running:
            info = read_progress(run_dir(self.root, self.spec, key))
            if info is None:
                continue
            trained[key] = steps_reached(info, self.spec)
            if info["phase"] == "train" and info["step"] > self.spec.warmup(key.algo):
                if info["sps"] > 0:  # learning, not its random warm-up
                    speeds.append(info["sps"] / train_rate(self.spec, key.algo))
        if speeds:
            speed = statistics.median(speeds)
            left = [run_seconds(self.spec, k, trained.get(k, 0)) for k in running + pending]
            return format_duration(schedule([t / speed + e for t, e in left], self.slots))
        if not self.durations:
            return "?"
        c = self.counts()
        left_s = (c["pending"] + c["running"] / 2) * sum(self.durations) / len(self.durations)
        return format_duration(left_s / self.slots)

    def tick(self) -> None:
        c = self.counts()
        running = [k for k, s in self.state.items() if s == "running"]
        if self._bar is not None:
            self._bar.set_postfix_str(
                f"pending {c['pending']} running {c['running']} done {c['done']} "
                f"failed {c['failed']} ETA {self.eta()}",
                refresh=False,
            )
            self._bar.refresh()
            for i, row in enumerate(self._rows):
                row.set_description_str(self._row(running[i]) if i < len(running) else "")
            return
        now = time.monotonic()
        if now - self._last_line >= self.interval:
            self._last_line = now
            rows = "; ".join(" ".join(self._row(k).split()) for k in running)
            print(
                f"[{time.strftime('%H:%M:%S')}] {c['done']}/{self.total} done, "
                f"{c['running']} running, {c['failed']} failed, {c['pending']} pending; "
                f"elapsed {format_duration(now - self.t0)}, ETA {self.eta()}"
                + (f" | {rows}" if rows else ""),
                file=self.stream,
                flush=True,
            )

    def close(self) -> None:
        for row in self._rows:
            row.close()
        if self._bar is not None:
            self._bar.close()


def pending_runs(root: Path, spec: Benchmark) -> tuple[list[RunKey], int]:
    """(runs without ``result.json``, number of finished runs)."""
    keys = spec.runs()
    todo = [k for k in keys if not (run_dir(root, spec, k) / rundir.RESULT).exists()]
    return todo, len(keys) - len(todo)


def kept_runs(root: Path, spec: Benchmark) -> str:
    """What an interrupted benchmark keeps of ``spec``'s grid in ``root``, read from the run
    directories: the finished runs, and of the others those trained (their evaluation goes on)
    or with a checkpoint (their training goes on); the rest start over."""
    keys = spec.runs()
    finished = trained = checkpointed = 0
    for key in keys:
        path = run_dir(root, spec, key)
        if (path / rundir.RESULT).exists():
            finished += 1
        elif rundir.finished_steps(path) is not None:
            trained += 1
        elif (path / rundir.CHECKPOINT).exists():
            checkpointed += 1
    text = f"{finished} of {len(keys)} runs finished in {Path(root) / 'runs'}"
    others = len(keys) - finished
    kept = [
        f"{n} {what}"
        for n, what in (
            (trained, "trained (their evaluation goes on)"),
            (checkpointed, "with a checkpoint (their training goes on)"),
        )
        if n
    ]
    if others and kept:
        text += f"; of the {others} others, " + " and ".join(kept)
    elif others:
        text += f"; the {others} others kept nothing yet"
    return text


def trained_steps(root: Path, spec: Benchmark, keys: list[RunKey]) -> dict[RunKey, int]:
    """The steps each of ``keys`` has trained in ``root`` by its last ``progress.json`` (a
    resumed run goes on from there; trained through: the budget), for those that have one."""
    out = {}
    for key in keys:
        progress = read_progress(run_dir(root, spec, key))
        if progress is not None and progress["step"] > 0:
            out[key] = steps_reached(progress, spec)
    return out


def steps_reached(progress: dict[str, Any], spec: Benchmark) -> int:
    """A run's trained steps by its ``progress.json``: its step while training, else the
    budget (it is evaluating)."""
    return progress["step"] if progress["phase"] == "train" else spec.steps


def plan(
    root: Path,
    spec: Benchmark,
    todo: int,
    finished: int,
    jobs: int,
    backend: str,
    pack: int = 1,
    left: list[RunKey] | None = None,
) -> str:
    """What is about to run, and the compute estimate (printed before anything starts): the
    whole grid's, and, in a benchmark resumed, that of the ``left`` runs, from the steps they
    have trained."""
    est = estimate(spec, jobs or 1)
    if spec.device.startswith("cuda"):
        from rrls.benchmark.gpu_estimate import describe

        estimate_line = "\n" + describe(spec, pack)
    else:
        estimate_line = (
            "\nestimate for the whole grid (from measured single-thread speeds on a 2-core CPU; "
            f"an estimate, +-30 %): {format_duration(est['cpu_s'])} of compute (training "
            f"{format_duration(est['train_s'])}, evaluation <= {format_duration(est['eval_s'])})"
            + (
                f", about {format_duration(est['wall_s'])} wall time with {jobs} parallel runs"
                if jobs
                else ", divided among the cluster's CPUs"
            )
        )
        trained = trained_steps(root, spec, left or [])
        if left is not None and (finished or trained):
            rest = estimate(spec, jobs or 1, runs=left, trained=trained)
            estimate_line += (
                f"; for the {len(left)} runs left ({len(trained)} part-trained, counted from "
                f"their last step): {format_duration(rest['cpu_s'])}"
                + (f", about {format_duration(rest['wall_s'])} wall time" if jobs else "")
            )
    return (
        f"rrls benchmark {root}: preset {spec.preset}, {len(spec.algos)} algorithms x "
        f"{len(spec.tasks)} tasks x {len(spec.seeds)} seeds = {est['runs']} runs "
        f"({finished} finished, {todo} to run), {spec.steps:,} steps each, set "
        f"{spec.uncertainty}, mesh {spec.mesh} x {spec.episodes} episodes; {backend} backend"
        + (f", split {spec.split} (training on the inner box)" if spec.split else "")
        + (f", {jobs} workers" if jobs else "")
        + (f", up to {pack} seeds of a cell trained together per process" if pack > 1 else "")
        + _simulators(spec)
        + estimate_line
    )


def _simulators(spec: Benchmark) -> str:
    """Where a warp benchmark's runs train: its tasks without a twin on CPU MuJoCo; a task's
    algorithms sharing each twin step."""
    if spec.simulator != "warp":
        return ""
    cpu = [t for t in spec.tasks if spec.simulator_for(t) != spec.simulator]
    shared = "; on the Warp twin a task's algorithms share each twin step"
    if not cpu:
        return shared
    return (
        f"; trained on the Warp twin but {', '.join(cpu)} (no twin: CPU MuJoCo, beside the "
        "twin's runs)" + shared
    )


def benchmark(
    out: str | Path,
    spec: Benchmark,
    jobs: int,
    backend: str = "local",
    ray_address: str | None = None,
    stream: TextIO | None = None,
    interval: float = 60.0,
    report: Callable[[Path], Path] | None = None,
    pack: int | None = None,
) -> int:
    """Run ``spec`` in ``out`` (resuming), then build the store, and the report with
    ``report(out)`` when given (``rrls benchmark`` passes :func:`rrls.report.make_report`; the
    report is the layer above, so this one is handed it rather than importing it).

    ``pack``: at most that many seeds of one (algorithm, task) cell are trained together in
    one process (``train_group``; same numbers as alone); default every seed of a cell on
    CUDA, 1 on CPU (``pipeline.default_pack``). Returns 0 when every run finished, 1 when some
    failed (the others still ran). Ctrl-C stops the runs, then raises an
    :class:`~rrls.interrupts.Interruption` saying what is kept (:func:`kept_runs`): the same
    call resumes from it.
    """
    from rrls.interrupts import keeping

    root = Path(out)
    with keeping(lambda: kept_runs(root, spec)):
        return _benchmark(root, spec, jobs, backend, ray_address, stream, interval, report, pack)


def _benchmark(
    root: Path,
    spec: Benchmark,
    jobs: int,
    backend: str,
    ray_address: str | None,
    stream: TextIO | None,
    interval: float,
    report: Callable[[Path], Path] | None,
    pack: int | None,
) -> int:
    from rrls.benchmark import benchfile

    stream = stream or sys.stderr
    root.mkdir(parents=True, exist_ok=True)
    with benchfile.locked(root):  # a concurrent `rrls submit` adding a task loses nothing
        stored = reconcile(root, spec)  # refuses another protocol; the grid may grow
        benchfile.write_spec(root, stored)
    todo, finished = pending_runs(root, spec)  # this command's grid only
    pack = default_pack(spec, pack)
    print(plan(root, spec, len(todo), finished, jobs, backend, pack, todo), file=stream, flush=True)
    slots = min(len(todo), (jobs or len(groups(todo, pack, spec))) * pack)  # runs at once
    display = Display(root, spec, todo, finished, slots, stream, interval)
    try:  # Ctrl-C: the runs are stopped before it goes on up
        if backend == "ray":
            run_ray(root, spec, todo, jobs, ray_address, display.event, display.tick, pack)
        else:
            run_local(root, spec, todo, jobs, display.event, display.tick, pack)
    finally:
        display.close()
    from rrls.benchmark.store import build_store

    with benchfile.reporting(root):  # a concurrent `rrls report` waits
        build_store(root, spec.fingerprints())
        if report is not None and (finished or len(display.failures) < len(todo)):
            path = report(root)  # (nothing finished: no report)
            print(f"report: {path}", file=stream)
    if display.failures:
        print(f"{len(display.failures)} run(s) failed:", file=stream)
        for key, detail in sorted(display.failures.items()):
            print(f"  {key.name(spec.uncertainty)}: {detail}", file=stream)
        return 1
    return 0
