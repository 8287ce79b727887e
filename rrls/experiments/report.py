"""``rrls report DIR``: summary.json, report.md, LaTeX/CSV tables and figures, from the store only.

Conventions (paper §5 and Appendix):

- a run's worst case is the minimum over mesh points of the mean return over the point's
  episodes, its average case the mean over points; a cell (task, algorithm) is the mean ± std
  (ddof=0) over seeds of those per-run numbers;
- normalised score: ``(v - v_TD3) / |v_M2TD3 - v_TD3|`` where ``v_TD3`` and ``v_M2TD3`` are the
  *seed means* of TD3 and M2TD3 on that task. Each seed of an algorithm is normalised with those
  references and the cell is the mean ± std over seeds — equal to normalising the seed mean (the
  map is affine), which is how the paper's Tables 4-5 follow from its raw tables (std = raw std /
  |v_M2TD3 - v_TD3|); the "Average" column is the mean over tasks of the means and of the stds;
- Table 6: per seed, the mean return of the protagonist against its own adversary over the
  episodes; the cell is mean ± std over seeds;
- references: a task whose benchmark has no finished TD3 and M2TD3 runs is normalised with a
  reference file's TD3 and M2TD3 means (``--reference``; ``rrls.experiments.reference``), and
  the report names the source of each task's normalisation;
- submitted algorithms (``rrls submit``) are rows like any other, marked as submitted.

The report never imports the training code: it reads ``DIR/results/`` (and ``benchmark.json``).
"""

from __future__ import annotations

import json
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np

from rrls.experiments import stats
from rrls.experiments.caveats import FEW, FEW_SEEDS_NOTE, few_seeds, unstable_normalisation
from rrls.experiments.names import NAMES, ORDER, sort_algos, task_name  # noqa: F401 - re-exported

METRICS = ("worst_case", "average_case")


#: with a train/test split (``evaluate(..., split=...)``): in- and out-of-distribution scores
SPLIT_METRICS = ("worst_case_id", "average_case_id", "worst_case_ood", "average_case_ood")


def split_scores(evaluations: Any) -> Any:
    """One row per (task, algorithm, seed): worst and average case over the in-distribution
    and the out-of-distribution mesh points separately (rows flagged ``in_distribution``)."""
    import pandas as pd

    keys = ["task", "algorithm", "seed"]
    flag = evaluations["in_distribution"].astype(str).str.lower() == "true"  # CSV or Parquet
    point = (
        evaluations.assign(in_distribution=flag)
        .groupby([*keys, "point", "in_distribution"], sort=True)["return"]
        .mean()
    )
    runs = point.reset_index()[keys].drop_duplicates().reset_index(drop=True)
    table = runs.copy()
    for value, tag in ((True, "id"), (False, "ood")):
        part = point[point.index.get_level_values("in_distribution") == value]
        scores = part.groupby(level=keys).agg(["min", "mean"]).reset_index()
        scores = scores.rename(columns={"min": f"worst_case_{tag}", "mean": f"average_case_{tag}"})
        table = (
            table.merge(scores, on=keys, how="left")
            if len(scores)
            else table.assign(**{f"worst_case_{tag}": np.nan, f"average_case_{tag}": np.nan})
        )
    return pd.DataFrame(table)


def paper_results() -> dict[str, Any]:
    """The paper's published raw, normalised and Table 6 numbers (package data)."""
    text = resources.files("rrls.experiments").joinpath("paper_results.json").read_text()
    return json.loads(text)


def summarise(root: str | Path, reference: Any = None) -> dict[str, Any]:
    """Everything ``summary.json`` holds, computed from the store. ``reference``: a
    ``rrls.experiments.reference.Reference`` (already checked against the benchmark) that
    normalises the tasks without their own TD3 and M2TD3 runs."""
    from rrls.experiments.store import load_store

    root = Path(root)
    tables = load_store(root)
    from rrls.experiments import benchfile

    spec_path = benchfile.spec_path(root)
    spec = benchfile.read_spec_json(root) if spec_path.exists() else None
    ev = tables["evaluations"]
    scores = stats.per_seed_scores(ev) if len(ev) else None
    present_tasks = list(dict.fromkeys(ev["task"])) if len(ev) else []
    present_algos = list(ev["algorithm"].unique()) if len(ev) else []
    tasks = list(dict.fromkeys([*(spec["tasks"] if spec else []), *present_tasks]))
    algos = sort_algos([*(spec["algos"] if spec else []), *present_algos])
    n_expected = len(spec["seeds"]) if spec else None
    uncertainty = spec["uncertainty"] if spec else (ev["uncertainty"].iloc[0] if len(ev) else None)

    def values(task: str, algo: str, metric: str) -> np.ndarray:
        if scores is None:
            return np.zeros(0)
        sel = scores[(scores["task"] == task) & (scores["algorithm"] == algo)]
        return sel.sort_values("seed")[metric].to_numpy(dtype=float)

    split = split_scores(ev) if len(ev) and "in_distribution" in ev else None

    def values_split(task: str, algo: str, metric: str) -> np.ndarray:
        sel = split[(split["task"] == task) & (split["algorithm"] == algo)]
        return sel.sort_values("seed")[metric].dropna().to_numpy(dtype=float)

    def norm_refs(task: str, metric: str) -> tuple[float, float, str] | None:
        """(v_TD3, v_M2TD3, source) of ``task``: the benchmark's seed means, else the
        reference's, else None (no normalised score)."""
        td3, m2td3 = values(task, "td3", metric), values(task, "m2td3", metric)
        if len(td3) and len(m2td3) and td3.mean() != m2td3.mean():
            return float(td3.mean()), float(m2td3.mean()), "benchmark"
        if reference is not None and uncertainty is not None:
            r_td3 = reference.mean(task, uncertainty, "td3", metric)
            r_m2td3 = reference.mean(task, uncertainty, "m2td3", metric)
            if r_td3 is not None and r_m2td3 is not None and r_td3 != r_m2td3:
                return r_td3, r_m2td3, "reference"
        return None

    def td3_seeds(task: str) -> np.ndarray:
        """TD3's per-seed worst cases: the benchmark's, else the reference's when it has them."""
        own = values(task, "td3", "worst_case")
        if len(own) or reference is None or uncertainty is None:
            return own
        row = reference.cell(task, uncertainty, "td3", "worst_case")
        return np.asarray(row["values"] if row and row.get("values") else [], dtype=float)

    dyn = tables["dynamic"]
    dyn_algos = set(dyn["algorithm"]) if len(dyn) and "algorithm" in dyn else set()
    out: dict[str, Any] = {}
    missing: list[str] = []
    normalisation: dict[str, dict[str, str | None]] = {}
    for task in tasks:
        out[task] = {}
        refs = {m: norm_refs(task, m) for m in METRICS}
        normalisation[task] = {m: (refs[m][2] if refs[m] else None) for m in METRICS}
        for algo in algos:
            cell: dict[str, Any] = {}
            for m in METRICS:
                cell[m] = stats.describe(values(task, algo, m), stats.rng_for(task, algo, m))
            n = cell["worst_case"]["n_seeds"]
            if n == 0:
                missing.append(f"{algo}/{task}: no finished run")
            elif n_expected and n < n_expected:
                missing.append(f"{algo}/{task}: {n} of {n_expected} seeds")
            cell["normalised"] = {}
            for m in METRICS:
                x = values(task, algo, m)
                if len(x) and refs[m] is not None:
                    z = stats.normalise(x, refs[m][0], refs[m][1])
                    cell["normalised"][m] = stats.describe(z, stats.rng_for(task, algo, m, "n"))
                else:
                    cell["normalised"][m] = None
            if algo in ("rarl", "nrmdp") or algo in dyn_algos:
                sel = dyn[(dyn["task"] == task) & (dyn["algorithm"] == algo)] if len(dyn) else dyn
                per_seed = sel.groupby("seed")["return"].mean() if len(sel) else []
                cell["dynamic"] = stats.describe(
                    np.asarray(per_seed), stats.rng_for(task, algo, "d")
                )
                cell["dynamic"]["episodes"] = len(sel)
            if split is not None:
                cell["split"] = {
                    m: stats.describe(values_split(task, algo, m), stats.rng_for(task, algo, m))
                    for m in SPLIT_METRICS
                }
            out[task][algo] = cell

    aggregate: dict[str, Any] = {}
    for algo in algos:
        agg: dict[str, Any] = {}
        for m in METRICS:
            per_task = []
            for task in tasks:
                ref = norm_refs(task, m)
                x = values(task, algo, m)
                if len(x) and ref is not None:
                    per_task.append(stats.normalise(x, ref[0], ref[1]))
            agg[f"normalised_{m}"] = stats.aggregate_iqm(per_task, stats.rng_for(algo, m, "agg"))
        if algo != "td3":
            pairs = [
                (values(t, algo, "worst_case"), td3_seeds(t))
                for t in tasks
                if len(values(t, algo, "worst_case")) and len(td3_seeds(t))
            ]
            agg["poi_over_td3_worst_case"] = stats.aggregate_poi(pairs, stats.rng_for(algo, "poi"))
        aggregate[algo] = agg
    versions = {}
    for col in ("rrls_version", "gymnasium_version", "mujoco_version"):
        if col in ev:
            versions[col.removesuffix("_version")] = sorted(map(str, ev[col].unique()))
    runs = tables["runs"]
    submitted: list[dict[str, Any]] = []
    if len(runs) and "source" in runs:
        for row in runs[runs["source"] == "submitted"].to_dict("records"):
            submitted.append(
                {
                    k: (None if isinstance(row.get(k), float) and np.isnan(row[k]) else row.get(k))
                    for k in ("algorithm", "task", "seed", "policy_kind", "policy_source")
                    + ("policy_sha256",)
                }
            )
            submitted[-1]["seed"] = int(submitted[-1]["seed"])
    return {
        "benchmark": spec,
        "uncertainty": uncertainty,
        "tasks": tasks,
        "algorithms": algos,
        "results": out,
        "aggregate": aggregate,
        "missing": missing,
        "versions": versions,
        "submitted": submitted,
        "normalisation": normalisation,
        "reference": None
        if reference is None
        else _reference_summary(reference, tasks, uncertainty),
        "conventions": {
            "worst_case": "per run: min over mesh points of the mean return over the point's "
            "episodes; cell: mean/std (ddof=0)/IQM/95% percentile-bootstrap CI of the mean over "
            "seeds",
            "average_case": "per run: mean over mesh points of the per-point mean return",
            "normalised": "(v - v_TD3) / |v_M2TD3 - v_TD3| with v_TD3, v_M2TD3 the seed means on "
            "the task (this benchmark's runs; without them, the reference file's means — see "
            "'normalisation'); applied to each seed, then mean/std over seeds (= normalising the "
            "seed mean, as the paper's Tables 4-5 do)",
            "aggregate": "IQM over all (task, seed) normalised scores with a stratified bootstrap "
            "CI (seeds resampled within tasks); mean_over_tasks/std_over_tasks: the paper's "
            "'Average' column",
            "poi_over_td3_worst_case": "P(algorithm's worst case > TD3's) for random seeds, "
            "averaged over tasks (TD3: this benchmark's runs, else the reference's per-seed "
            "values); stratified bootstrap CI",
            "split": "with a train/test split of the set: worst/average case over the "
            "in-distribution (training part) and out-of-distribution (test part) mesh points "
            "separately, per run; cell: mean/std over seeds",
            "dynamic": "per seed: mean return against the run's own adversary over its episodes; "
            "cell: mean/std over seeds (paper Table 6)",
            "bootstrap": f"scipy.stats.bootstrap, percentile, {stats.N_RESAMPLES} resamples, "
            "generator seeded from the cell's name",
        },
    }


# --- formatting -----------------------------------------------------------------------------
def _fmt(value: float | None, digits: int = 2) -> str:
    if value is None or not np.isfinite(value):
        return "–"
    return f"{round(value, digits) + 0.0:,.{digits}f}"  # + 0.0: no "-0.00"


def _pm(cell: dict[str, Any] | None, digits: int = 2) -> str:
    if not cell or cell.get("mean") is None:
        return "–"
    if cell.get("n_seeds") == 1:  # one seed: its value, no "± 0.00"
        return f"{_fmt(cell['mean'], digits)}{FEW}"
    return f"{_fmt(cell['mean'], digits)} ± {_fmt(cell['std'], digits)}" + (
        FEW if few_seeds(cell) else ""
    )


def _tex_pm(cell: dict[str, Any] | None, digits: int = 2, bold: bool = False) -> str:
    if not cell or cell.get("mean") is None:
        return "--"
    mean, std = (round(cell[k], digits) + 0.0 for k in ("mean", "std"))
    body = f"{mean:.{digits}f} \\pm {std:.{digits}f}"
    if cell.get("n_seeds") == 1:
        body = f"{mean:.{digits}f}^{{\\dagger}}"
    elif few_seeds(cell):
        body += "^{\\dagger}"
    return f"$\\mathbf{{{body}}}$" if bold else f"${body}$"


def _paper_cell(paper: dict[str, Any], table: str, algo: str, task: str) -> Any:
    return paper.get(table, {}).get(algo, {}).get(task)


TABLES = {
    # name: (title, cell getter, paper table, digits)
    "raw_worst_case": ("Raw static worst case (paper Appendix, Table 7)", "worst_case", 2),
    "raw_average_case": ("Raw static average case (paper Appendix, Table 8)", "average_case", 2),
    "normalised_worst_case": ("Normalised static worst case (paper Table 4)", "n:worst_case", 2),
    "normalised_average_case": (
        "Normalised static average case (paper Table 5)",
        "n:average_case",
        2,
    ),
    "dynamic": ("Against the run's own adversary (paper Table 6)", "dynamic", 2),
}


def _cell(summary: dict[str, Any], task: str, algo: str, getter: str) -> dict[str, Any] | None:
    cell = summary["results"].get(task, {}).get(algo)
    if cell is None:
        return None
    if getter.startswith("n:"):
        return cell["normalised"].get(getter[2:])
    return cell.get(getter)


def _rows(summary: dict[str, Any], name: str) -> list[str]:
    if name != "dynamic":
        return list(summary["algorithms"])
    return [
        a
        for a in summary["algorithms"]
        if a in ("rarl", "nrmdp")
        or any("dynamic" in summary["results"][t].get(a, {}) for t in summary["tasks"])
    ]


def _reference_summary(reference: Any, tasks: list[str], uncertainty: str | None) -> dict:
    """The reference's metadata and its cells for the benchmark's tasks (for the report)."""
    rows = [
        r
        for r in reference.rows
        if r["task"] in tasks and r["uncertainty"] == uncertainty and r["metric"] != "dynamic"
    ]
    return {**reference.describe(), "rows": rows}


def _label(summary: dict[str, Any], algo: str) -> str:
    """An algorithm's name in the report; submitted ones are marked."""
    name = NAMES.get(algo, algo)
    if any(s["algorithm"] == algo for s in summary.get("submitted") or []):
        return f"{name} (submitted)"
    return name


def write_tables(summary: dict[str, Any], out: Path, paper: dict[str, Any]) -> list[Path]:
    """``tables/<name>.tex`` (booktabs, the paper's layout: algorithms × tasks) and ``.csv``."""
    import pandas as pd

    from rrls._io import atomic_write_bytes, atomic_write_table

    out.mkdir(parents=True, exist_ok=True)
    written = []
    tasks = summary["tasks"]
    same_protocol = summary["uncertainty"] == paper["uncertainty"]
    for name, (title, getter, digits) in TABLES.items():
        algos = _rows(summary, name)
        normalised = name.startswith("normalised")
        rows = []
        for algo in algos:
            for task in tasks:
                cell = _cell(summary, task, algo, getter) or {}
                pub = _paper_cell(paper, name, algo, task) if same_protocol else None
                rows.append(
                    {
                        "algorithm": algo,
                        "task": task,
                        "mean": cell.get("mean"),
                        "std": cell.get("std"),
                        "iqm": cell.get("iqm"),
                        "ci95_low": (cell.get("ci95") or [None, None])[0],
                        "ci95_high": (cell.get("ci95") or [None, None])[1],
                        "n_seeds": cell.get("n_seeds", 0),
                        "paper_mean": pub[0] if isinstance(pub, list) else pub,
                        "paper_std": pub[1] if isinstance(pub, list) else None,
                    }
                )
        atomic_write_table(out / f"{name}.csv", pd.DataFrame(rows))
        # LaTeX: bold the best mean of each column (as the paper does)
        best = {}
        for task in tasks:
            means = [(_cell(summary, task, a, getter) or {}).get("mean") for a in algos]
            finite = [m for m in means if m is not None]
            best[task] = max(finite) if finite else None
        # Table 6 as the paper prints it: each task in its own unit (10^k), no bold (the paper:
        # the two algorithms play different adversaries, so no ranking)
        scale = {t: paper["dynamic_scale"].get(t, 1.0) if name == "dynamic" else 1.0 for t in tasks}
        cols = [
            task_name(t) + (f" ($10^{round(np.log10(scale[t]))}$)" if scale[t] != 1 else "")
            for t in tasks
        ] + (["Average"] if normalised else [])
        lines = [
            "% " + title + " -- generated by `rrls report`",
            "\\begin{table}[h]",
            "\\centering",
            f"\\caption{{{title}}}",
            "\\begin{tabular}{l" + "c" * len(cols) + "}",
            "\\toprule",
            " & " + " & ".join(cols) + " \\\\",
            "\\midrule",
        ]
        for algo in algos:
            cells = []
            for task in tasks:
                cell = _cell(summary, task, algo, getter)
                is_best = (
                    cell is not None
                    and cell.get("mean") is not None
                    and (cell["mean"] == best[task])
                    and name != "dynamic"
                )
                if cell and cell.get("mean") is not None and scale[task] != 1:
                    cell = {k: cell[k] / scale[task] for k in ("mean", "std")}
                cells.append(_tex_pm(cell, digits, bold=is_best and len(algos) > 1))
            if normalised:
                agg = summary["aggregate"].get(algo, {}).get(f"normalised_{getter[2:]}", {})
                avg = {"mean": agg.get("mean_over_tasks"), "std": agg.get("std_over_tasks")}
                cells.append(_tex_pm(avg, digits))
            lines.append(f"{NAMES.get(algo, algo)} & " + " & ".join(cells) + " \\\\")
        lines += ["\\bottomrule", "\\end{tabular}", f"\\label{{tab:rrls-{name}}}", "\\end{table}"]
        atomic_write_bytes(out / f"{name}.tex", ("\n".join(lines) + "\n").encode())
        written += [out / f"{name}.tex", out / f"{name}.csv"]
    return written


def _md_table(summary: dict[str, Any], name: str, paper: dict[str, Any]) -> list[str]:
    title, getter, digits = TABLES[name]
    tasks = summary["tasks"]
    algos = _rows(summary, name)
    if not algos:
        return []
    same_protocol = summary["uncertainty"] == paper["uncertainty"]
    normalised = name.startswith("normalised")
    head = ["algorithm", *[task_name(t) for t in tasks]] + (
        ["Average", "IQM [95% CI]"] if normalised else []
    )
    lines = [f"### {title}", "", "| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for algo in algos:
        row = [_label(summary, algo)]
        for task in tasks:
            text = _pm(_cell(summary, task, algo, getter), digits)
            pub = _paper_cell(paper, name, algo, task) if same_protocol else None
            if pub is not None:
                pub_text = (
                    f"{_fmt(pub[0])} ± {_fmt(pub[1])}" if isinstance(pub, list) else _fmt(pub)
                )
                text += f" (paper {pub_text})"
            row.append(text)
        if normalised:
            agg = summary["aggregate"].get(algo, {}).get(f"normalised_{getter[2:]}", {})
            row.append(_pm({"mean": agg.get("mean_over_tasks"), "std": agg.get("std_over_tasks")}))
            ci = agg.get("ci95")
            row.append(
                f"{_fmt(agg.get('iqm'))} [{_fmt(ci[0])}, {_fmt(ci[1])}]"
                if ci
                else _fmt(agg.get("iqm"))
            )
        lines.append("| " + " | ".join(row) + " |")
    return [*lines, ""]


def make_report(root: str | Path, plots: bool = True, reference: Any = None) -> Path:
    """Write ``root/report/`` (summary.json, report.md, tables/, figures) from the store.

    ``reference``: a reference file's path, a shipped name (``paper``) or a loaded
    ``Reference``; refused (``ReferenceError``) unless measured under the benchmark's protocol.
    """
    from rrls._io import atomic_write_bytes, atomic_write_json

    root = Path(root)
    if reference is not None:
        from rrls.experiments.reference import Reference, check_compatible, load_reference

        if not isinstance(reference, Reference):
            reference = load_reference(reference)
        from rrls.experiments import benchfile

        if not benchfile.spec_path(root).exists():
            raise ValueError(f"{root} holds no benchmark.json: a reference needs its protocol")
        check_compatible(reference, benchfile.read_spec_json(root))
    summary = summarise(root, reference)
    paper = paper_results()
    out = root / "report"
    out.mkdir(parents=True, exist_ok=True)
    atomic_write_json(out / "summary.json", summary)
    write_tables(summary, out / "tables", paper)
    per_run = _per_run(root, out / "tables")
    figures: list[tuple[str, Path]] = []
    if plots:
        try:
            from rrls.experiments import plots as plotting
            from rrls.experiments.store import load_store

            figures = plotting.make_figures(load_store(root), summary, out / "figures")
        except ImportError as err:  # matplotlib is optional
            figures = []
            summary.setdefault("notes", []).append(f"figures skipped: {err}")
    text = _markdown(summary, paper, figures, out)
    if per_run:  # after the static tables: each run's nominal return beside its scores
        dynamic = "## Dynamic evaluation"
        text = text.replace(dynamic, "\n".join(per_run) + "\n" + dynamic, 1)
    atomic_write_bytes(out / "report.md", text.encode())
    return out / "report.md"


def _per_run(root: Path, tables: Path) -> list[str]:
    """``tables/per_run.csv`` and its ``report.md`` section (none for an empty store)."""
    from rrls._io import atomic_write_table
    from rrls.experiments.per_run import per_run_lines, per_run_table
    from rrls.experiments.store import load_store

    table = per_run_table(load_store(root))
    if not len(table):
        return []
    atomic_write_table(tables / "per_run.csv", table)
    return per_run_lines(table, list(ORDER))


def _split_table(summary: dict[str, Any]) -> list[str]:
    """In- and out-of-distribution worst/average case, when the evaluations had a split."""
    cells = [
        (t, a, summary["results"][t][a]["split"])
        for t in summary["tasks"]
        for a in summary["algorithms"]
        if "split" in summary["results"][t].get(a, {})
    ]
    if not cells:
        return []
    kind = (summary.get("benchmark") or {}).get("split")
    lines = [
        "## In and out of distribution (train/test split of the set)",
        "",
        *(
            [
                f"Split {kind}: in distribution (ID), the inner box the runs trained on; out of "
                "distribution (OOD), the rest of the set's mesh.",
                "",
            ]
            if kind
            else []
        ),
        "| task | algorithm | worst ID | average ID | worst OOD | average OOD |",
        "|---|---|---|---|---|---|",
    ]
    for task, algo, cell in cells:
        row = " | ".join(_pm(cell[m]) for m in SPLIT_METRICS)
        lines.append(f"| {task} | {NAMES.get(algo, algo)} | {row} |")
    return [*lines, ""]


def _markdown(
    summary: dict[str, Any], paper: dict[str, Any], figures: list[tuple[str, Path]], out: Path
) -> str:
    spec = summary.get("benchmark") or {}
    lines = ["# rrls benchmark report", ""]
    if spec:
        lines += [
            f"- preset `{spec.get('preset')}`: {len(spec['algos'])} built-in algorithms × "
            f"{len(spec['tasks'])} tasks × {len(spec['seeds'])} seeds, {spec['steps']:,} "
            f"training steps per run, set `{spec['uncertainty']}`, mesh {spec['mesh']} per "
            f"dimension × {spec['episodes']} episodes, dynamic evaluation "
            f"{spec['dynamic_episodes']} episodes",
        ]
        reduced = (
            spec["steps"] < paper["steps"]
            or spec["uncertainty"] != paper["uncertainty"]
            or len(spec["seeds"]) < paper["seeds"]
        )
        if reduced:
            lines.append(
                "- **Reduced budget: not the paper's protocol** (5 M steps, 10 seeds, the 3D "
                "sets of five tasks). Numbers are not comparable with the paper's."
            )
    if summary.get("versions"):
        lines.append(
            "- versions: " + ", ".join(f"{k} {'/'.join(v)}" for k, v in summary["versions"].items())
        )
    lines.append(
        "- paper numbers are shown beside a cell only when the set is the paper's (`3d`)"
        if summary["uncertainty"] != paper["uncertainty"]
        else "- `(paper ...)`: the paper's published number for the same cell"
    )
    lines.append("")
    if summary["missing"]:
        lines += ["## Missing cells", ""] + [f"- {m}" for m in summary["missing"]] + [""]
    lines += _normalisation_lines(summary)
    lines += ["## Static evaluation", ""]
    cells = [
        c
        for by_algo in summary["results"].values()
        for metrics in by_algo.values()
        for c in metrics.values()
        if isinstance(c, dict)
    ]
    if any(few_seeds(c) for c in cells):
        lines += [FEW_SEEDS_NOTE, ""]
    for name in ("raw_worst_case", "raw_average_case", "normalised_worst_case"):
        lines += _md_table(summary, name, paper)
    lines += _md_table(summary, "normalised_average_case", paper)
    if "nrmdp" in summary["algorithms"] and summary["uncertainty"] == paper["uncertainty"]:
        lines += [
            "Known erratum: the paper prints 0.44 for NR-MDP's normalised average case on Ant; "
            "its own raw numbers give 0.54.",
            "",
        ]
    lines += _split_table(summary)
    lines += [
        "## Dynamic evaluation (paper Table 6)",
        "",
        "Raw returns of the protagonist against its own final adversary (`tables/dynamic.tex` "
        "prints them in the paper's per-task units).",
        "",
    ] + _md_table(summary, "dynamic", paper)
    poi = [
        (a, v["poi_over_td3_worst_case"])
        for a, v in summary["aggregate"].items()
        if "poi_over_td3_worst_case" in v
    ]
    if poi:
        lines += [
            "## Probability of improvement over TD3 (worst case)",
            "",
            "| algorithm | P(better than TD3) | 95% CI | tasks |",
            "|---|---|---|---|",
        ]
        for algo, p in poi:
            ci = p.get("ci95")
            ci_text = f"[{_fmt(ci[0])}, {_fmt(ci[1])}]" if ci else "–"
            lines.append(
                f"| {_label(summary, algo)} | {_fmt(p['value'])} | {ci_text} | {p['n_tasks']} |"
            )
        lines.append("")
    lines += _reference_lines(summary)
    lines += _submitted_lines(summary)
    if figures:
        lines += ["## Figures", ""]
        for caption, path in figures:
            lines += [f"**{caption}**", "", f"![{caption}]({path.relative_to(out).as_posix()})", ""]
    lines += ["## Conventions", ""]
    lines += [f"- **{k}**: {v}" for k, v in summary["conventions"].items()]
    lines += ["", "Tables for papers: `tables/*.tex` (booktabs) and `tables/*.csv`.", ""]
    return "\n".join(lines)


def _normalisation_lines(summary: dict[str, Any]) -> list[str]:
    """Which TD3 / M2TD3 means normalise each task: the benchmark's, a reference's, or none."""
    ref = summary.get("reference")
    sources: dict[str, list[str]] = {}
    for task in summary["tasks"]:
        used = {v for v in summary.get("normalisation", {}).get(task, {}).values()}
        key = "reference" if "reference" in used else "benchmark" if "benchmark" in used else "-"
        sources.setdefault(key, []).append(task)
    lines = ["## Normalisation", ""]
    if sources.get("benchmark"):
        lines.append(
            f"- this benchmark's own TD3 and M2TD3 runs: {', '.join(sources['benchmark'])}"
        )
    if sources.get("reference") and ref:
        spec = summary.get("benchmark") or {}
        budget = ""
        if ref.get("steps") and spec.get("steps") and ref["steps"] != spec["steps"]:
            budget = (
                f"; **its budget differs**: {ref['steps']:,} training steps per run there, "
                f"{spec['steps']:,} here"
            )
        lines.append(
            f"- the reference **{ref['label']}** (`{ref['file']}`, physics {ref['physics']}, "
            f"mesh {ref['mesh']} x {ref['episodes']} episodes{budget}): "
            f"{', '.join(sources['reference'])}"
        )
    if sources.get("-"):
        lines.append(
            "- none (no finished TD3 and M2TD3 runs here"
            + (" nor in the reference" if ref else "; `rrls report DIR --reference FILE`")
            + f"): {', '.join(sources['-'])}"
        )
    lines += unstable_normalisation(summary)
    return [*lines, ""]


def _reference_lines(summary: dict[str, Any]) -> list[str]:
    """The reference's own cells for the benchmark's tasks, normalised like the benchmark."""
    ref = summary.get("reference")
    if not ref or not ref.get("rows"):
        return []
    tasks = [t for t in summary["tasks"] if any(r["task"] == t for r in ref["rows"])]
    algos = sort_algos(r["algorithm"] for r in ref["rows"])
    lines = [
        f"## Reference: {ref['label']}",
        "",
        f"`{ref['file']}`: physics {ref['physics']}, set {summary['uncertainty']}, mesh "
        f"{ref['mesh']} x {ref['episodes']} episodes"
        + (f", {ref['steps']:,} training steps per run" if ref.get("steps") else "")
        + ". Mean ± std over its seeds (n).",
        "",
    ]
    by_key = {(r["task"], r["algorithm"], r["metric"]): r for r in ref["rows"]}
    for metric, title in (("worst_case", "worst case"), ("average_case", "average case")):
        head = ["algorithm", *[task_name(t) for t in tasks]]
        lines += [f"### Reference {title}", "", "| " + " | ".join(head) + " |"]
        lines.append("|" + "---|" * len(head))
        for algo in algos:
            cells = []
            for task in tasks:
                row = by_key.get((task, algo, metric))
                if row is None:
                    cells.append("–")
                    continue
                text = _pm({"mean": row["mean"], "std": row["std"]})
                text += f" ({row['n_seeds']})" if row.get("n_seeds") else ""
                cells.append(text)
            lines.append(f"| {NAMES.get(algo, algo)} | " + " | ".join(cells) + " |")
        lines.append("")
    return lines


def _submitted_lines(summary: dict[str, Any]) -> list[str]:
    """Where the submitted policies came from (``rrls submit``'s provenance)."""
    rows = summary.get("submitted") or []
    if not rows:
        return []
    lines = [
        "## Submitted policies",
        "",
        "Evaluated by `rrls submit` under this benchmark's protocol (same set, mesh, episodes "
        "and episode seeds as its own runs); not trained here.",
        "",
        "| algorithm | task | seed | kind | source | sha256 |",
        "|---|---|---|---|---|---|",
    ]
    for r in rows:
        sha = (r.get("policy_sha256") or "")[:12] or "–"
        lines.append(
            f"| {r['algorithm']} | {r['task']} | {r['seed']} | {r.get('policy_kind') or '–'} "
            f"| `{r.get('policy_source') or '–'}` | {sha} |"
        )
    return [*lines, ""]
