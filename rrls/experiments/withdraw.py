"""``rrls withdraw``: take submitted runs out of a benchmark, so that later reports stay
complete (a task no run is left on leaves a submissions-only benchmark's task list)."""

from __future__ import annotations

from pathlib import Path

from rrls.experiments.submission import SubmitError, load_spec

__all__ = ["remove_submission"]


def remove_submission(
    bench_dir: str | Path, algo: str, task: str | None = None, seed: int | None = None
) -> list[str]:
    """Take submitted runs of ``algo`` (all, or of ``task`` / ``seed``) out of ``bench_dir``;
    a task no run is left on, in a submissions-only benchmark, leaves its task list too, so
    later reports stay complete. Returns the removed runs' names. A benchmark's own runs
    (trained by ``rrls benchmark``) are refused: they are its baselines."""
    import shutil
    from dataclasses import replace

    from rrls import rundir
    from rrls.experiments import benchfile

    root = Path(bench_dir)
    spec = load_spec(root)
    removed = []
    with benchfile.locked(root):
        for run in sorted((root / "runs").glob("*/")):
            try:
                result = rundir.read_checked_json(run / rundir.RESULT)
            except (OSError, ValueError):
                continue
            if result.get("algorithm") != algo:
                continue
            if (task is not None and result.get("task") != task) or (
                seed is not None and int(result.get("seed", -1)) != seed
            ):
                continue
            if "submitted" not in result:
                raise SubmitError(
                    f"{run.name} is one of the benchmark's own runs, not a submission: "
                    "remove nothing"
                )
            removed.append(run)
        if not removed:
            which = " ".join(
                x for x in (algo, task and f"on {task}", seed is not None and f"seed {seed}") if x
            )
            raise SubmitError(f"no submission of {which} in {root}")
        for run in removed:
            shutil.rmtree(run)
        if not spec.algos:  # a submissions-only benchmark: drop the tasks left without runs
            left = {
                rundir.read_checked_json(p).get("task")
                for p in (root / "runs").glob(f"*/{rundir.RESULT}")
            }
            tasks = tuple(t for t in spec.tasks if t in left) or spec.tasks
            if tasks != spec.tasks:
                benchfile.write_spec(root, replace(spec, tasks=tasks))
    return [r.name for r in removed]
