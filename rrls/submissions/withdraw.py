"""``rrls withdraw``: take submitted runs out of a benchmark, so that later reports stay
complete (a task no run is left on leaves a submissions-only benchmark's task list).

All or nothing: every ``result.json`` the change depends on is read and checked first (a
damaged one is a one-line error and nothing is removed), then the runs and the task list
change together under the benchmark's lock (:mod:`rrls.benchmark.changes`)."""

from __future__ import annotations

from pathlib import Path

from rrls.submissions.steps import SubmitError, load_spec

__all__ = ["remove_submission"]


def remove_submission(
    bench_dir: str | Path, algo: str, task: str | None = None, seed: int | None = None
) -> list[str]:
    """Take submitted runs of ``algo`` (all, or of ``task`` / ``seed``) out of ``bench_dir``;
    a task no run is left on, in a submissions-only benchmark, leaves its task list too, so
    later reports stay complete. Returns the removed runs' names. A benchmark's own runs
    (trained by ``rrls benchmark``) are refused: they are its baselines. ``algo`` and ``task``
    are matched in any spelling ``rrls submit`` accepts (``InvertedPendulum``, ``My-SAC``)."""
    from dataclasses import replace

    from rrls import files, rundir
    from rrls.benchmark import benchfile
    from rrls.benchmark.changes import Changes
    from rrls.files import json_bytes
    from rrls.tasks import get_task

    root = Path(bench_dir)
    spec = load_spec(root)
    if task is not None:
        try:
            task = get_task(task).key
        except ValueError as err:
            raise SubmitError(str(err)) from None
    with benchfile.locked(root):
        results = {}
        for run in sorted((root / "runs").glob("*/")):
            if not (run / rundir.RESULT).exists():
                continue  # unfinished: neither a submission nor a task's finished run
            try:  # every result first: a damaged one stops the command before any change
                results[run] = files.read_checked_json(run / rundir.RESULT)
            except ValueError as err:
                raise SubmitError(f"{err}; nothing was withdrawn") from None
        name = _submitted_name(algo, {str(r.get("algorithm")) for r in results.values()})
        removed = []
        for run, result in results.items():
            if result.get("algorithm") != name:
                continue
            if (task is not None and result.get("task") != task) or (
                seed is not None and result.get("seed") != seed
            ):
                continue
            if "submitted" not in result:
                raise SubmitError(
                    f"{run.name} is one of the benchmark's own runs, not a submission: "
                    "nothing was withdrawn"
                )
            removed.append(run)
        if not removed:
            which = " ".join(
                x for x in (algo, task and f"on {task}", seed is not None and f"seed {seed}") if x
            )
            raise SubmitError(f"no submission of {which} in {root}")
        tasks = spec.tasks
        if not spec.algos:  # a submissions-only benchmark: drop the tasks left without runs
            left = {r.get("task") for run, r in results.items() if run not in removed}
            tasks = tuple(t for t in spec.tasks if t in left) or spec.tasks
        with Changes(root) as change:
            for run in removed:
                change.remove(run)
            if tasks != spec.tasks:
                data = json_bytes(replace(spec, tasks=tasks).to_json())
                change.write(benchfile.spec_path(root), data)
    return [r.name for r in removed]


def _submitted_name(algo: str, names: set[str]) -> str:
    """``algo`` as the benchmark stores it: itself, else the one stored name equal to it in
    any case (``rrls submit`` refuses names that differ only by case from a reserved one)."""
    if algo in names:
        return algo
    same = [n for n in names if n.lower() == algo.lower()]
    return same[0] if len(same) == 1 else algo
