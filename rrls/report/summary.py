"""``summary.json``: the report's numbers, computed from the store in three parts.

- **cells**: per (task, algorithm) the seed statistics of the worst case, the average case, their
  normalised scores, the dynamic return and the in/out-of-distribution scores; the same for a
  reference's rows (``reference_results``), so every table can put them beside the benchmark's;
- **aggregates**: per algorithm, across tasks: the IQM of the normalised scores and the
  probability of improvement over the normalised score's 0 anchor (stratified bootstrap CIs);
- **provenance**: the protocol, the versions, the submitted policies, where each task's
  normalisation came from and whether it is stable.

The scores themselves are ``rrls.evaluation.metrics``' (one definition); the statistics are
``rrls.report.stats``'; the two algorithms whose means are the normalised score's 0 and 1
are the algorithm table's (``rrls.algorithms.normalisers``).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from rrls.algorithms import normalisers, plays_adversary
from rrls.evaluation.metrics import (
    SCORES,
    SPLIT_SCORES,
    normalized_score,
    normalized_std,
    split_run_scores,
)
from rrls.files import loads_json
from rrls.report import stats
from rrls.report.caveats import check_normaliser
from rrls.report.names import normaliser_names, sort_algos
from rrls.report.pairwise import summarise_pairs
from rrls.report.rechecked import summarise_rechecked
from rrls.schema import SchemaError

__all__ = ["CONVENTIONS", "Scores", "reference_name", "summarise", "summarise_store"]

#: the normalised score's anchors (0, 1) as a reader sees them: their display names
_ZERO, _ONE = normaliser_names()

CONVENTIONS = {
    "worst_case": "per run: min over mesh points of the mean return over the point's "
    "episodes; cell: mean/std (ddof=0)/IQM/95% Student-t CI of the mean over seeds "
    "(mean ± t(0.975, n-1)·s/√n, s with ddof=1: honest at 3-5 seeds, where a percentile "
    "bootstrap cannot leave the values' range)",
    "average_case": "per run: mean over mesh points of the per-point mean return",
    "normalised": f"(v - v_{_ZERO}) / |v_{_ONE} - v_{_ZERO}| with v_{_ZERO}, v_{_ONE} the seed "
    "means on the task (this benchmark's runs; without them, the reference file's means — see "
    "'normalisation'); applied to each seed, then mean/std over seeds (= normalising the "
    "seed mean, as the paper's Tables 4-5 do)",
    "aggregate": "IQM over all (task, seed) normalised scores with a stratified bootstrap "
    "CI (seeds resampled within tasks); mean_over_tasks/std_over_tasks: the paper's "
    "'Average' column",
    # the key names its baseline as summary.json has always spelled it
    "poi_over_td3_worst_case": f"P(algorithm's worst case > {_ZERO}'s) for random seeds, "
    f"averaged over tasks ({_ZERO}: this benchmark's runs, else the reference's per-seed "
    "values); stratified bootstrap CI",
    "split": "with a train/test split of the set: worst/average case over the "
    "in-distribution (training part) and out-of-distribution (test part) mesh points "
    "separately, per run; cell: mean/std over seeds",
    "dynamic": "per seed: mean return against the run's own adversary over its episodes; "
    "cell: mean/std over seeds (paper Table 6)",
    "bootstrap": f"scipy.stats.bootstrap, percentile, {stats.N_RESAMPLES} resamples, "
    "generator seeded from the cell's name",
    "unstable_normalisation": f"a task's normaliser |v_{_ONE} - v_{_ZERO}| within the two "
    "baselines' seed spread (max std), or under 5% of their magnitude (both failed alike): its "
    "normalised scores divide by noise and are flagged",
}


def reference_name(reference: Any) -> str:
    """The short name a reference's rows carry in tables (``TD3 (quick)``): the shipped name or
    the file's stem, else its label."""
    path = getattr(reference, "path", None)
    return Path(str(path)).stem if path else str(reference.label)


class Scores:
    """Per-seed values of every (task, algorithm, score) of a store, and the references that
    normalise each task: what the cells and the aggregates are computed from."""

    def __init__(self, tables: dict[str, Any], reference: Any, uncertainty: str | None) -> None:
        ev = tables["evaluations"]
        self.table = stats.per_seed_scores(ev) if len(ev) else None
        self.split = split_run_scores(ev) if len(ev) and "in_distribution" in ev else None
        self.dynamic = tables["dynamic"]
        self.reference = reference
        self.uncertainty = uncertainty

    def values(self, task: str, algo: str, metric: str) -> np.ndarray:
        """Per-seed ``metric`` (a score or a split score) of ``algo`` on ``task``, by seed."""
        table = self.split if metric in SPLIT_SCORES else self.table
        if table is None:
            return np.zeros(0)
        sel = table[(table["task"] == task) & (table["algorithm"] == algo)].sort_values("seed")
        column = sel[metric].dropna() if metric in SPLIT_SCORES else sel[metric]
        return column.to_numpy(dtype=float)

    def dynamic_values(self, task: str, algo: str) -> tuple[np.ndarray, int]:
        """Per-seed mean return against the run's own adversary, and the episodes behind it."""
        dyn = self.dynamic
        sel = dyn[(dyn["task"] == task) & (dyn["algorithm"] == algo)] if len(dyn) else dyn
        per_seed = sel.groupby("seed")["return"].mean() if len(sel) else []
        return np.asarray(per_seed, dtype=float), len(sel)

    def reference_row(self, task: str, algo: str, metric: str) -> dict[str, Any] | None:
        if self.reference is None or self.uncertainty is None:
            return None
        return self.reference.cell(task, self.uncertainty, algo, metric)

    def norm_refs(self, task: str, metric: str) -> dict[str, Any] | None:
        """``{zero, one, zero_std, one_std, source}`` normalising ``task``: the seed means (and
        stds) of the score's two anchors (``rrls.algorithms.normalisers``), the benchmark's, else
        the reference's, else None (no normalised score)."""
        zero, one = (self.values(task, a, metric) for a in normalisers())
        if len(zero) and len(one) and zero.mean() != one.mean():
            return {
                "zero": float(zero.mean()),
                "one": float(one.mean()),
                "zero_std": float(zero.std()),
                "one_std": float(one.std()),
                "source": "benchmark",
            }
        r_zero, r_one = (self.reference_row(task, a, metric) for a in normalisers())
        if r_zero is not None and r_one is not None and r_zero["mean"] != r_one["mean"]:
            return {
                "zero": float(r_zero["mean"]),
                "one": float(r_one["mean"]),
                "zero_std": float(r_zero.get("std") or 0.0),
                "one_std": float(r_one.get("std") or 0.0),
                "source": "reference",
            }
        return None

    def zero_seeds(self, task: str) -> np.ndarray:
        """The 0 anchor's per-seed worst cases (the Y of ``poi_over_td3_worst_case``): the
        benchmark's, else the reference's when it has them."""
        zero = normalisers()[0]
        own = self.values(task, zero, "worst_case")
        if len(own):
            return own
        row = self.reference_row(task, zero, "worst_case")
        return np.asarray(row["values"] if row and row.get("values") else [], dtype=float)


def summarise(root: str | Path, reference: Any = None) -> dict[str, Any]:
    """Everything ``summary.json`` holds, computed from the store. ``reference``: a
    ``rrls.report.reference.Reference`` (already checked against the benchmark) that
    normalises the tasks without their own runs of the normalised score's anchors and whose rows
    the tables show."""
    from rrls.benchmark import benchfile
    from rrls.benchmark.store import load_store

    root = Path(root)
    spec = benchfile.read_spec_json(root) if benchfile.spec_path(root).exists() else None
    return summarise_store(load_store(root), spec, reference)


def summarise_store(
    tables: dict[str, Any], spec: dict[str, Any] | None, reference: Any = None
) -> dict[str, Any]:
    """``summarise`` of a store already loaded and its benchmark's ``spec`` (``None``: the tasks,
    algorithms and set are read from the evaluations): what a report over several benchmarks
    (``rrls.report.crosstask``) summarises with their stores joined."""
    ev = tables["evaluations"]
    tasks = list(
        dict.fromkeys([*(spec["tasks"] if spec else []), *(ev["task"] if len(ev) else [])])
    )
    algos = sort_algos([*(spec["algos"] if spec else []), *(ev["algorithm"] if len(ev) else [])])
    uncertainty = spec["uncertainty"] if spec else (ev["uncertainty"].iloc[0] if len(ev) else None)
    scores = Scores(tables, reference, uncertainty)
    by_task = (spec or {}).get("by_task") or {}  # joined benchmarks: each task its seeds
    expected = {t: len((by_task.get(t) or spec or {}).get("seeds") or []) for t in tasks}
    results, missing = cells(scores, tasks, algos, expected if spec else None)
    refs = {t: {m: scores.norm_refs(t, m) for m in SCORES} for t in tasks}
    # a reference trained with another budget (shown only when asked) is normalised by its own
    # anchors' means: this benchmark's would mix budgets in one score
    own_norm = bool(spec) and reference is not None and reference.steps != spec.get("steps")
    return {
        "benchmark": spec,
        "uncertainty": uncertainty,
        "tasks": tasks,
        "algorithms": algos,
        "results": results,
        "aggregate": aggregates(scores, tasks, algos),
        "pairwise": summarise_pairs(scores.values, tasks, algos),
        "rechecked": summarise_rechecked(tables["runs"]),
        "missing": missing,
        **provenance(tables),
        "normalisation": {
            t: {m: r and r["source"] for m, r in by.items()} for t, by in refs.items()
        },
        "unstable": unstable(refs),
        "reference": None
        if reference is None
        else {
            **_reference_summary(reference, tasks, uncertainty),
            "normalised_by": f"its own {_ZERO} and {_ONE}"
            if own_norm
            else "this report's normalisers",
        },
        "reference_results": None
        if reference is None
        else reference_cells(scores, tasks, own_normaliser=own_norm),
        "conventions": CONVENTIONS,
    }


def cells(
    scores: Scores, tasks: list[str], algos: list[str], n_expected: dict[str, int] | None
) -> tuple[dict[str, Any], list[str]]:
    """Per task and algorithm, the seed statistics of every score; and the missing cells
    (``n_expected``: each task's planned seeds)."""
    dyn = scores.dynamic
    dyn_algos = set(dyn["algorithm"]) if len(dyn) and "algorithm" in dyn else set()
    out: dict[str, Any] = {}
    missing: list[str] = []
    for task in tasks:
        out[task] = {}
        refs = {m: scores.norm_refs(task, m) for m in SCORES}
        for algo in algos:
            cell: dict[str, Any] = {
                m: stats.describe(scores.values(task, algo, m), stats.rng_for(task, algo, m))
                for m in SCORES
            }
            n = cell["worst_case"]["n_seeds"]
            if n == 0:
                missing.append(f"{algo}/{task}: no finished run")
            elif n_expected and n < n_expected[task]:
                missing.append(f"{algo}/{task}: {n} of {n_expected[task]} seeds")
            cell["normalised"] = {}
            for m in SCORES:
                x, ref = scores.values(task, algo, m), refs[m]
                cell["normalised"][m] = (
                    stats.describe(
                        stats.normalise(x, ref["zero"], ref["one"]),
                        stats.rng_for(task, algo, m, "n"),
                    )
                    if len(x) and ref is not None
                    else None
                )
            if plays_adversary(algo) or algo in dyn_algos:
                values, episodes = scores.dynamic_values(task, algo)
                cell["dynamic"] = stats.describe(values, stats.rng_for(task, algo, "d"))
                cell["dynamic"]["episodes"] = episodes
            if scores.split is not None:
                cell["split"] = {
                    m: stats.describe(scores.values(task, algo, m), stats.rng_for(task, algo, m))
                    for m in SPLIT_SCORES
                }
            out[task][algo] = cell
    return out, missing


def aggregates(scores: Scores, tasks: list[str], algos: list[str]) -> dict[str, Any]:
    """Per algorithm: the normalised scores' IQM over (task, seed) and P(improvement over the
    score's 0 anchor)."""
    zero = normalisers()[0]
    out: dict[str, Any] = {}
    for algo in algos:
        agg: dict[str, Any] = {}
        for m in SCORES:
            per_task = []
            for task in tasks:
                ref, x = scores.norm_refs(task, m), scores.values(task, algo, m)
                if len(x) and ref is not None:
                    per_task.append(stats.normalise(x, ref["zero"], ref["one"]))
            agg[f"normalised_{m}"] = stats.aggregate_iqm(per_task, stats.rng_for(algo, m, "agg"))
            agg[f"normalised_{m}"]["min_seeds"] = min((len(x) for x in per_task), default=0)
        if algo != zero:
            pairs = [
                (scores.values(t, algo, "worst_case"), scores.zero_seeds(t))
                for t in tasks
                if len(scores.values(t, algo, "worst_case")) and len(scores.zero_seeds(t))
            ]
            poi = stats.aggregate_poi(pairs, stats.rng_for(algo, "poi"))
            poi["min_seeds"] = min((min(len(x), len(y)) for x, y in pairs), default=0)
            agg["poi_over_td3_worst_case"] = poi
        out[algo] = agg
    return out


def provenance(tables: dict[str, Any]) -> dict[str, Any]:
    """The library versions of the evaluations, where the submitted policies came from, the
    trained runs' budgets (``run_steps``: per algorithm, its runs' steps) and what finished
    (``finished_runs``: per source, trained or submitted, its algorithms, tasks and seeds)."""
    ev, runs = tables["evaluations"], tables["runs"]
    versions = {}
    for col in ("rrls_version", "gymnasium_version", "mujoco_version"):
        if col in ev:
            versions[col.removesuffix("_version")] = sorted(map(str, ev[col].unique()))
    submitted: list[dict[str, Any]] = []
    if len(runs) and "source" in runs:
        for row in runs[runs["source"] == "submitted"].to_dict("records"):
            keys = ("algorithm", "task", "seed", "policy_kind", "policy_source", "policy_sha256")
            entry = {
                k: (None if isinstance(row.get(k), float) and np.isnan(row[k]) else row.get(k))
                for k in keys
            }
            budget = row.get("budget")
            budget = _budget(budget) if isinstance(budget, str) and budget else {}
            steps = int(row["steps"]) if row.get("steps") else None
            submitted.append(
                {**entry, "seed": int(entry["seed"]), "steps": steps or None, "budget": budget}
            )
    trained = runs[runs["source"] != "submitted"] if len(runs) and "source" in runs else runs
    run_steps = {
        str(a): sorted({int(s) for s in by["steps"]})
        for a, by in (trained.groupby("algorithm") if len(trained) and "steps" in trained else [])
    }
    finished = {
        str(source): {
            "algorithms": sort_algos(map(str, by["algorithm"])),
            "tasks": sorted({str(t) for t in by["task"]}),
            "seeds": sorted({int(s) for s in by["seed"]}),
            "runs": len(by),
        }
        for source, by in (runs.groupby("source") if len(runs) and "source" in runs else [])
    }
    return {
        "versions": versions,
        "submitted": submitted,
        "run_steps": run_steps,
        "finished_runs": finished,
    }


def _budget(text: str) -> dict[str, Any]:
    """A submitted run's budget as the store's runs table holds it (JSON of an object)."""
    where = "results/runs: column 'budget'"
    value = loads_json(text, where)
    if not isinstance(value, dict):
        raise SchemaError(f"{where} holds {text!r:.60}; valid: a JSON object")
    return value


def unstable(refs: dict[str, dict[str, dict[str, Any] | None]]) -> list[dict[str, Any]]:
    """The (task, score) whose normaliser divides by noise (``caveats.check_normaliser``)."""
    out = []
    for task, by_metric in refs.items():
        for metric, ref in by_metric.items():
            if ref is None:
                continue
            reason = check_normaliser(ref["zero"], ref["zero_std"], ref["one"], ref["one_std"])
            if reason:
                span = abs(ref["one"] - ref["zero"])
                out.append(
                    {"task": task, "metric": metric, "source": ref["source"], "span": span}
                    | {"reason": reason}
                )
    return out


def reference_cells(
    scores: Scores, tasks: list[str], own_normaliser: bool = False
) -> dict[str, Any]:
    """The reference's cells for the benchmark's tasks, shaped like ``results``' (the raw
    scores, their normalised scores with this report's normalisers, or with the reference's own
    anchors' means when ``own_normaliser``, the dynamic return), so a table shows them as
    rows. A cell's CI needs the reference's per-seed values."""
    ref = scores.reference
    out: dict[str, Any] = {}
    name = reference_name(ref)
    for task in tasks:
        norm = {
            m: _own_norm(scores, task, m) if own_normaliser else scores.norm_refs(task, m)
            for m in SCORES
        }
        for algo in sort_algos(ref.algorithms()):
            cell: dict[str, Any] = {"normalised": {}}
            for m in (*SCORES, "dynamic"):
                row = scores.reference_row(task, algo, m)
                if row is None:
                    continue
                cell[m] = _row_cell(row, None, stats.rng_for(name, task, algo, m))
                if m in SCORES and norm[m] is not None:
                    cell["normalised"][m] = _row_cell(
                        row, norm[m], stats.rng_for(name, task, algo, m, "n")
                    )
            if len(cell) > 1:
                out.setdefault(task, {})[algo] = cell
    return out


def _own_norm(scores: Scores, task: str, metric: str) -> dict[str, Any] | None:
    """The reference's own means of the two anchors on ``task`` (None without both, or equal)."""
    zero, one = (scores.reference_row(task, a, metric) for a in normalisers())
    if zero is None or one is None or zero["mean"] == one["mean"]:
        return None
    return {"zero": float(zero["mean"]), "one": float(one["mean"])}


def _row_cell(row: dict[str, Any], norm: dict[str, Any] | None, rng: Any) -> dict[str, Any]:
    """A reference row as a cell: its mean, std and seeds, the CI from its per-seed values
    when it has them; normalised (an affine map) by ``norm``'s anchors' means."""
    mean, std = float(row["mean"]), None if row.get("std") is None else float(row["std"])
    values = np.asarray(row.get("values") or [], dtype=float)
    if norm is not None:
        zero, one = norm["zero"], norm["one"]
        mean = float(normalized_score(mean, zero, one))
        std = None if std is None else normalized_std(std, zero, one)
        values = stats.normalise(values, zero, one) if len(values) else values
    described = stats.describe(values, rng) if len(values) else {}
    n = row.get("n_seeds") or len(values) or None
    return {
        "mean": mean,
        "std": std,
        "iqm": described.get("iqm"),
        "ci95": described.get("ci95"),
        "n_seeds": n,
    }


def _reference_summary(reference: Any, tasks: list[str], uncertainty: str | None) -> dict:
    """The reference's metadata and its rows for the benchmark's tasks (for the report)."""
    rows = [
        r
        for r in reference.rows
        if r["task"] in tasks and r["uncertainty"] == uncertainty and r["metric"] != "dynamic"
    ]
    return {**reference.describe(), "name": reference_name(reference), "rows": rows}
