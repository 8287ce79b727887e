"""The side of ``rrls submit`` that runs and writes: the evaluation under the benchmark's
protocol (the same as the benchmark's own runs) and the installation of the run directory."""

from __future__ import annotations

import json
import shutil
import time
from pathlib import Path
from typing import Any

from rrls.experiments.spec import Spec
from rrls.physics import is_paper


def discard(staging: Path, made: list[Path]) -> None:
    """Remove a submission's staging directory and the directories it created."""
    shutil.rmtree(staging, ignore_errors=True)
    for path in reversed(made):
        try:
            path.rmdir()  # only if empty: another command's files stay
        except OSError:
            pass


def jsonable(meta: dict[str, Any]) -> dict[str, Any]:
    return json.loads(json.dumps(meta, default=str))


def run_evaluation(
    spec: Spec,
    algo: str,
    task: str,
    seed: int,
    policy: Any,
    out: Path,
    workers: int | None,
    progress: bool | None,
) -> dict[str, Any]:
    """The final mesh evaluation of the benchmark's runs (``pipeline``'s), into ``out/eval``."""
    from rrls.evaluation import evaluate

    meta = getattr(policy, "metadata", None) or {}
    result = evaluate(
        policy,
        task,
        spec.uncertainty,
        nb_mesh_dim=spec.mesh,
        episodes=spec.episodes,
        seed=spec.eval_seed,
        workers=workers,
        out_dir=out / "eval",
        paper=is_paper(spec.physics),
        split=spec.split_of(task),
        progress=progress,
    )
    return {
        "algorithm": algo,
        "task": task,
        "uncertainty": spec.uncertainty,
        "train_set": str(meta.get("uncertainty") or "unknown"),
        **({"split": spec.split, **result.split_scores()} if spec.split else {}),
        "seed": seed,
        "steps": int(meta.get("steps") or 0),  # the training budget when the policy records it
        "physics": spec.physics,
        "worst_case": result.worst_case,
        "average_case": result.average_case,
        "versions": result.config.get("versions", {}),
    }


def run_dynamic(
    spec: Spec, task: str, policy: Any, adversary: Any, game: str, alpha: float | None, out: Path
) -> dict[str, Any]:
    """The dynamic evaluation as the benchmark's RARL / NR-MDP runs play it (``dynamic.csv``)."""
    from rrls.evaluation import evaluate_dynamic
    from rrls.rundir import write_checked_table

    result = evaluate_dynamic(
        policy,
        adversary,
        task,
        game=game,
        uncertainty=spec.uncertainty,
        episodes=spec.dynamic_episodes,
        seed=spec.eval_seed,
        alpha=0.1 if alpha is None else float(alpha),
        paper=is_paper(spec.physics),
        **_rate_game(spec, game, policy, adversary),
    )
    write_checked_table(out / "dynamic.csv", result.episodes)
    return {"dynamic_mean": result.mean, "dynamic_std": result.std, "dynamic_env": result.env_id}


def _rate_game(spec: Spec, game: str, policy: Any, adversary: Any) -> dict[str, Any]:
    """The benchmark's rate-limited game for ``evaluate_dynamic``: TC-RMDP's (or rrls's earlier
    target game), the protagonist's view and the adversary's omniscience as their files say."""
    from rrls.evaluation.stack import policy_view

    if game != "adversarial" or spec.rate_limit is None:
        return {"rate_limit": None}
    view = policy_view(policy)
    meta = getattr(adversary, "metadata", None) or {}
    return {
        "rate_limit": spec.rate_limit,
        "rate_game": spec.rate_game,
        "observe": "vanilla" if view is None else view.observe,
        "history": 1 if view is None else view.history,
        "omniscient": bool(meta.get("omniscient", True)),
    }


def install(root: Path, staging: Path, final: Path, result: dict[str, Any]) -> None:
    """Move the evaluated ``staging`` directory to ``final`` (replacing a previous submission
    only once the new one is complete); ``result.json`` goes in last, as for trained runs."""
    from rrls.experiments.store import write_result

    (staging / "eval" / ".lock").unlink(missing_ok=True)
    final.parent.mkdir(parents=True, exist_ok=True)
    trash = None
    if final.exists():
        trash = root / "submissions" / ".replaced" / f"{final.name}-{time.time_ns()}"
        trash.parent.mkdir(parents=True, exist_ok=True)
        final.rename(trash)
    staging.rename(final)
    write_result(final, result)
    if trash is not None:
        shutil.rmtree(trash, ignore_errors=True)
