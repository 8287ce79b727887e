"""A benchmark's results written as a reference file (``rrls report DIR --export-reference``):
the per-seed rows and where they came from. The file format itself is ``reference``'s."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from rrls.report.reference import (
    VERSION_KEYS,
    Reference,
    ReferenceError,
    benchmark_protocol,
)


def export_reference(
    root: str | Path,
    path: str | Path,
    label: str | None = None,
    algos: list[str] | None = None,
    notes: str | None = None,
) -> Reference:
    """Write the results of the benchmark in ``root`` (every algorithm, or ``algos``) as a
    reference file another lab can normalise and compare with; returns it. ``notes`` is what a
    reader must know that the numbers do not say (a reduced budget, runs made in pieces)."""
    from rrls.benchmark import benchfile
    from rrls.benchmark.store import load_store
    from rrls.report import stats

    root = Path(root)
    spec = benchfile.read_spec_json(root)
    tables = load_store(root)
    ev, dyn = tables["evaluations"], tables["dynamic"]
    if not len(ev):
        raise ReferenceError(f"{root} holds no finished run to export")
    scores = stats.per_seed_scores(ev)
    wanted = list(dict.fromkeys(algos or scores["algorithm"]))
    unknown = [a for a in wanted if a not in set(scores["algorithm"])]
    if unknown:
        raise ReferenceError(
            f"no runs of {', '.join(unknown)} in {root}; it has: "
            f"{', '.join(dict.fromkeys(scores['algorithm']))}"
        )
    rows = []
    for (task, algo), group in scores.groupby(["task", "algorithm"], sort=True):
        if algo not in wanted:
            continue
        group = group.sort_values("seed")
        seeds = group["seed"].to_numpy()
        for metric in ("worst_case", "average_case"):
            rows.append(
                _row(task, spec["uncertainty"], algo, metric, group[metric].to_numpy(), seeds)
            )
        if len(dyn):
            sel = dyn[(dyn["task"] == task) & (dyn["algorithm"] == algo)]
            if len(sel):
                per_seed = sel.groupby("seed")["return"].mean()
                rows.append(
                    _row(
                        task,
                        spec["uncertainty"],
                        algo,
                        "dynamic",
                        per_seed.to_numpy(),
                        per_seed.index.to_numpy(),
                    )
                )
    versions = {}
    for key in VERSION_KEYS:
        col = f"{key}_version"
        if col in ev:
            versions[key] = "/".join(sorted(map(str, ev[col].unique())))
    proto = benchmark_protocol(spec)
    ref = Reference(
        label=label or f"{root.resolve().name} ({spec.get('preset', 'custom')} preset)",
        physics=proto["physics"],
        mesh=proto["mesh"],
        episodes=proto["episodes"],
        endpoint=proto["endpoint"],
        steps=int(spec["steps"]),
        eval_seed=int(spec.get("eval_seed", 0)),
        versions=versions,
        notes=notes or f"exported by `rrls report --export-reference` from {root.resolve().name}",
        rows=rows,
        provenance=provenance(root, spec, wanted),
    )
    ref.save(path)
    ref.path = str(path)
    return ref


def provenance(root: Path, spec: dict[str, Any], algos: list[str]) -> dict[str, Any]:
    """Where a benchmark's numbers came from, from its spec and its runs' ``run.json``: the
    preset, budget and hyper-parameters, and every rrls commit, library version, machine and
    device that trained a run (more than one value: the runs were produced in pieces)."""
    from rrls import __version__, rundir
    from rrls.benchmark import store

    runs: dict[str, Any] = {}
    for directory in sorted(p for p in (root / "runs").glob("*") if p.is_dir()):
        run: dict[str, Any] = {}
        for read in (store.read_result, rundir.read_run_json):  # run.json has the machine
            try:
                run.update(read(directory))
            except FileNotFoundError:  # unfinished, or submitted (no training)
                continue
        if run.get("algorithm") in algos:
            runs[directory.name] = run

    def distinct(values: Any) -> list[Any]:
        out: list[Any] = []
        for v in values:
            if v is not None and v not in out:
                out.append(v)
        return out

    versions: dict[str, list[str]] = {}
    for run in runs.values():
        for key, value in (run.get("versions") or {}).items():
            versions.setdefault(key, [])
            if value not in versions[key]:
                versions[key].append(value)
    prov = [run.get("provenance") or {} for run in runs.values()]
    # runs re-evaluated under today's protocol but trained under other settings say how, per
    # algorithm (``result.json``'s ``trained_otherwise``): a reader of the reference must know
    otherwise: dict[str, Any] = {}
    for run in runs.values():
        if run.get("trained_otherwise"):
            otherwise.setdefault(run["algorithm"], run["trained_otherwise"])
    # the hyper-parameters each algorithm's runs trained with (``run.json``), where the spec
    # leaves them to each algorithm's own table (its null batch size, learning rate, warm-up)
    hyper: dict[str, list[Any]] = {}
    for run in runs.values():
        resolved = (run.get("config") or {}).get("hyper")
        if resolved:
            seen = hyper.setdefault(run["algorithm"], [])
            if resolved not in seen:
                seen.append(resolved)
    out = {
        "preset": spec.get("preset"),
        "physics": spec.get("physics"),
        "uncertainty": spec.get("uncertainty"),
        "steps": spec.get("steps"),
        "seeds": spec.get("seeds"),
        "learning_starts": spec.get("learning_starts"),
        "hidden": spec.get("hidden"),
        "learning_rate": spec.get("learning_rate"),
        "batch_size": spec.get("batch_size"),
        "mesh": spec.get("mesh"),
        "episodes": spec.get("episodes"),
        "dynamic_episodes": spec.get("dynamic_episodes"),
        "runs": len(runs),
        "exported_with_rrls": __version__,
        "versions": {k: sorted(map(str, v)) for k, v in sorted(versions.items())},
        "commits": distinct(e.get("commit") for r in runs.values() for e in rundir.executions(r)),
        "machines": distinct(e.get("machine") for r in runs.values() for e in rundir.executions(r)),
        "devices": distinct(p.get("device") for p in prov),
    }
    if hyper:  # one dict per algorithm; a list where its runs trained with more than one
        out["hyperparameters"] = {a: h[0] if len(h) == 1 else h for a, h in sorted(hyper.items())}
    if otherwise:
        out["trained_otherwise"] = dict(sorted(otherwise.items()))
    return out


def _row(
    task: str, uncertainty: str, algo: str, metric: str, values: Any, seeds: Any
) -> dict[str, Any]:
    """One reference row: the mean and (population) std over the seeds, each seed's value and
    which seed it is."""
    import numpy as np

    values = np.asarray(values, dtype=float)
    return {
        "task": task,
        "uncertainty": uncertainty,
        "algorithm": algo,
        "metric": metric,
        "mean": float(values.mean()),
        "std": float(values.std()),
        "n_seeds": len(values),
        "values": [float(v) for v in values],
        "seeds": [int(s) for s in seeds],
    }


__all__ = ["export_reference", "provenance"]
