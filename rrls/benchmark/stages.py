"""The stages every entry of a benchmark goes through after training, on one code path for the
benchmark's own runs (``pipeline``) and submitted policies (``submission``), so the two cannot
drift: the final evaluation over the mesh under the benchmark's ``Protocol``, and the dynamic
evaluation of a protagonist against an adversary (RARL, NR-MDP)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from rrls.benchmark.grid import Benchmark

__all__ = ["run_dynamic", "run_evaluation"]


def run_evaluation(
    spec: Benchmark,
    algo: str,
    task: str,
    seed: int,
    policy: Any,
    out: Path,
    workers: int | None,
    progress: bool | None,
    trained: dict[str, Any] | None = None,
) -> dict[str, Any]:
    """The final mesh evaluation under the benchmark's protocol, into ``out/eval``; the
    ``result.json`` fields it gives. ``trained``: what the benchmark knows of the training
    (its ``train_set`` and ``steps``); a submitted policy's own metadata says it otherwise."""
    from rrls.evaluation import evaluate

    meta = getattr(policy, "metadata", None) or {}
    result = evaluate(
        policy,
        task,
        protocol=spec.protocol,
        workers=workers,
        out_dir=out / "eval",
        progress=progress,
    )
    rechecked = {}
    if spec.protocol.recheck is not None:  # fresh episodes at the lowest points (docs/evaluation)
        from rrls.evaluation.recheck import recheck

        how = spec.protocol.recheck
        rechecked = recheck(policy, task, spec.protocol, result.episodes, how, workers, progress)
    trained = trained or {
        "train_set": str(meta.get("uncertainty") or "unknown"),
        "steps": int(meta.get("steps") or 0),  # the training budget when the policy records it
    }
    return {
        "algorithm": algo,
        "task": task,
        "uncertainty": spec.uncertainty,
        "train_set": trained["train_set"],
        **({"split": spec.split, **result.split_scores()} if spec.split else {}),
        "seed": seed,
        "steps": trained["steps"],
        "physics": spec.physics,
        "protocol": spec.fingerprints()["protocol"],
        "worst_case": result.worst_case,
        "average_case": result.average_case,
        # the training's record (torch included) where the policy carries one
        "versions": meta.get("versions") or result.config.get("versions", {}),
        **rechecked,
    }


def run_dynamic(
    spec: Benchmark,
    task: str,
    policy: Any,
    adversary: Any,
    game: str,
    alpha: float | None,
    out: Path,
) -> dict[str, Any]:
    """The dynamic evaluation (paper Table 6): ``policy`` against ``adversary`` in ``game``
    (``adversarial``: RARL's; ``nr``/``pr``: NR-/PR-MDP's with ``alpha``), under the protocol's
    rate-limited game if it has one; writes ``out/dynamic.csv``."""
    from rrls.evaluation import evaldir, evaluate_dynamic

    result = evaluate_dynamic(
        policy,
        adversary,
        task,
        game=game,
        alpha=0.1 if alpha is None else float(alpha),
        protocol=spec.protocol,
        **_players(policy, adversary),
    )
    evaldir.write_dynamic(out, result.episodes)
    return {"dynamic_mean": result.mean, "dynamic_std": result.std, "dynamic_env": result.env_id}


def _players(policy: Any, adversary: Any) -> dict[str, Any]:
    """What the players' files say of a rate-limited game (TC-RMDP): the protagonist's view and
    the adversary's omniscience; the protocol gives the game itself."""
    from rrls.evaluation.stack import policy_view

    view = policy_view(policy)
    meta = getattr(adversary, "metadata", None) or {}
    return {
        "observe": "vanilla" if view is None else view.observe,
        "history": 1 if view is None else view.history,
        "omniscient": bool(meta.get("omniscient", True)),
    }
