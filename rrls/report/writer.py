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
  reference file's TD3 and M2TD3 means (``--reference``; ``rrls.report.reference``), and
  the report names the source of each task's normalisation;
- submitted algorithms (``rrls submit``) are rows like any other, marked as submitted.

The report never imports the training code: it reads ``DIR/results/`` (and ``benchmark.json``).
"""

from __future__ import annotations

from importlib import resources
from pathlib import Path
from typing import Any

from rrls.benchmark.changes import rebuild_folder
from rrls.evaluation.metrics import SPLIT_SCORES
from rrls.files import loads_json
from rrls.report.caveats import (
    FEW,
    FEW_SEEDS_NOTE,
    UNSTABLE_NOTE,
    few_seeds,
    unstable_normalisation,
)
from rrls.report.cells import fmt, pm
from rrls.report.crosstask import sources_lines
from rrls.report.latex import fit_file
from rrls.report.names import ORDER, display_name, normaliser_names
from rrls.report.origins import budget_lines, reference_lines, submitted_lines
from rrls.report.pairwise import markdown as pairwise_markdown
from rrls.report.pairwise import paper_orderings
from rrls.report.pairwise import write_tables as write_pairwise
from rrls.report.rechecked import markdown as rechecked_markdown
from rrls.report.summary import summarise, summarise_store
from rrls.report.tables import label, md_table, terminal_table, write_tables

__all__ = [
    "make_cross_report",
    "make_report",
    "paper_results",
    "summarise",
    "terminal_table",
    "write_report",
]


def paper_results() -> dict[str, Any]:
    """The paper's published raw, normalised and Table 6 numbers (package data)."""
    text = resources.files("rrls.report").joinpath("paper_results.json").read_text()
    return loads_json(text, "paper_results.json")


def make_report(
    root: str | Path,
    plots: bool = True,
    reference: Any = None,
    labels: dict[str, str] | None = None,
    titles: bool = True,
    cells: str = "ci",
    allow_other_budget: bool = False,
) -> Path:
    """Write ``root/report/`` (summary.json, report.md, tables/, figures) from the store,
    whole or not at all: built beside the old report, which it replaces once complete.

    ``reference``: a reference file's path, a shipped name (``paper``) or a loaded
    ``Reference``; refused (``ReferenceError``) unless measured under the benchmark's protocol
    and, unless ``allow_other_budget`` (then its rows are marked ‡ and normalised by its own TD3
    and M2TD3), trained with the benchmark's budget. ``cells``: each LaTeX cell ``ci``
    (``mean [95 % CI]``) or ``pm`` (``mean ± std``, the paper's).
    ``labels``: ``{algorithm (or algorithm@reference): row name}`` for every table and figure.
    ``titles=False``: figures without titles, for a paper whose captions say what they show.
    """
    from rrls.benchmark.store import load_store

    root = Path(root)
    if reference is not None:
        from rrls.report.reference import Reference, check_compatible, load_reference

        if not isinstance(reference, Reference):
            reference = load_reference(reference)
        from rrls.benchmark import benchfile

        if not benchfile.spec_path(root).exists():
            raise ValueError(f"{root} holds no benchmark.json: a reference needs its protocol")
        check_compatible(reference, benchfile.read_spec_json(root), other_budget=allow_other_budget)
    _check_has_runs(root)
    summary = summarise(root, reference)
    return write_report(root, load_store(root), summary, plots, reference, labels, titles, cells)


def make_cross_report(
    dirs: list[str | Path],
    out: str | Path,
    plots: bool = True,
    labels: dict[str, str] | None = None,
    titles: bool = True,
    cells: str = "ci",
) -> Path:
    """Write ``out/report/`` over several benchmarks (``rrls.report.crosstask.joined``:
    each task from one of them, normalised by its own TD3 and M2TD3), as ``make_report``
    writes one benchmark's: the paper's Tables 4-5 across the tasks, whole or not at all."""
    from rrls.report.crosstask import joined

    tables, spec = joined(list(dirs))
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    summary = summarise_store(tables, spec)
    return write_report(out, tables, summary, plots, None, labels, titles, cells)


def write_report(
    root: Path,
    store: dict[str, Any],
    summary: dict[str, Any],
    plots: bool,
    reference: Any,
    labels: dict[str, str] | None,
    titles: bool,
    cells: str,
) -> Path:
    """``root/report/`` from a summary and the store it was computed from."""
    from rrls.files import atomic_write_bytes, atomic_write_json

    if labels:
        summary["labels"] = dict(labels)
    summary["table_cells"] = cells
    paper = paper_results()
    summary["paper_orderings"] = paper_orderings(summary, paper)

    def build(out: Path) -> None:  # into a new folder, swapped in whole once complete
        _, skipped = write_tables(summary, out / "tables", paper, cells)
        write_pairwise(summary, out / "tables", lambda a: label(summary, a))
        for path in sorted((out / "tables").glob("pairwise_*.tex")):
            fit_file(path)  # never wider than the line, as the other tables
        summary["tables_not_written"] = skipped
        per_run = _per_run(store, out / "tables", summary)
        figures: list[tuple[str, Path]] = []
        if plots:
            try:
                from rrls.report import plots as plotting

                figures = plotting.make_figures(
                    store, summary, out / "figures", reference, titles=titles
                )
            except ImportError as err:  # matplotlib is optional
                figures = []
                summary.setdefault("notes", []).append(f"figures skipped: {err}")
        atomic_write_json(out / "summary.json", summary)
        text = _markdown(summary, paper, figures, out)
        if per_run:  # after the static tables: each run's nominal return beside its scores
            dynamic = "## Dynamic evaluation"
            text = text.replace(dynamic, "\n".join(per_run) + "\n" + dynamic, 1)
        atomic_write_bytes(out / "report.md", text.encode())

    return rebuild_folder(root, "report", build) / "report.md"


def _check_has_runs(root: Path) -> None:
    """A benchmark none of whose runs finished has nothing to report: say so in one line."""
    from rrls.benchmark.store import load_store

    if len(load_store(root)["evaluations"]):
        return
    failed = sorted(p.parent.name for p in (root / "runs").glob("*/error.txt"))
    why = f"{len(failed)} failed (see {root / 'runs'}/*/error.txt)" if failed else "none ran"
    raise ValueError(f"{root}: no run has finished ({why}); there is nothing to report yet")


def _per_run(store: dict[str, Any], tables: Path, summary: dict[str, Any]) -> list[str]:
    """``tables/per_run.csv`` (each row's label beside its algorithm) and its ``report.md``
    section (none for an empty store)."""
    from rrls.files import atomic_write_table
    from rrls.report.per_run import per_run_lines, per_run_table

    table = per_run_table(store)
    if not len(table):
        return []
    table.insert(2, "label", [label(summary, a) for a in table["algorithm"]])
    atomic_write_table(tables / "per_run.csv", table)
    return per_run_lines(table, list(ORDER), lambda a: label(summary, a))


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
        row = " | ".join(pm(cell[m]) for m in SPLIT_SCORES)
        lines.append(f"| {task} | {display_name(algo)} | {row} |")
    return [*lines, ""]


def _beyond_the_paper(spec: dict[str, Any]) -> list[str]:
    """The report's line on what the benchmark's protocol adds to the paper's evaluation
    (disruptors, a schedule, an episode limit: ``Benchmark.flat_json`` names them when given), so
    that no one reads its numbers as the paper's."""
    parts = []
    if spec.get("disruptors"):
        parts.append("disruptors " + ", ".join(f"`{n}` {v}" for n, v in spec["disruptors"]))
    if spec.get("schedule"):
        grid = ", ".join(f"{k} {v}" for k, v in spec["schedule"]["grid"].items())
        parts.append(f"a `{spec['schedule']['kind']}` schedule meshed over {grid}")
    if spec.get("max_episode_steps"):
        parts.append(f"episodes of at most {spec['max_episode_steps']:,} steps (training too)")
    if not parts:
        return []
    return [f"- evaluated under {'; '.join(parts)}: not the paper's static evaluation"]


def _markdown(
    summary: dict[str, Any], paper: dict[str, Any], figures: list[tuple[str, Path]], out: Path
) -> str:
    spec = summary.get("benchmark") or {}
    lines = ["# rrls benchmark report", ""]
    by_task = spec.get("by_task") or {}
    budgets = budget_lines(summary)  # a section only where other sources have budgets
    if by_task:  # several benchmarks joined (rrls.report.crosstask): per task below
        lines.append(
            f"- {len(by_task)} benchmarks joined, one per task: {_counts(summary)}, set "
            f"`{spec['uncertainty']}`, mesh {spec['mesh']} per dimension; each task's budget, "
            "seeds and episodes under Sources below"
        )
    elif spec:
        elsewhere = " (other sources: Budgets below)" if budgets else ""
        lines += [
            f"- preset `{spec.get('preset')}`: {_counts(summary)}, {spec['steps']:,} "
            f"training steps per run trained here{elsewhere}, set "
            f"`{spec['uncertainty']}`, mesh {spec['mesh']} per "
            f"dimension × {spec['episodes']} episodes, dynamic evaluation "
            f"{spec['dynamic_episodes']} episodes",
        ]
    if spec:
        steps = [t.get("steps") or 0 for t in by_task.values()] or [spec["steps"]]
        reduced = (
            max(steps) < paper["steps"]
            or spec["uncertainty"] != paper["uncertainty"]
            or len(spec["seeds"]) < paper["seeds"]
        )
        if reduced:
            lines.append(
                "- **Reduced budget: not the paper's protocol** (5 M steps, 10 seeds, the 3D "
                "sets of five tasks). Numbers are not comparable with the paper's."
            )
        if spec.get("simulator", "mujoco") != "mujoco":
            from rrls.twin.catalog import TWIN_TASKS

            cpu = [t for t in spec["tasks"] if t not in TWIN_TASKS]
            lines.append(
                f"- trained on the **{spec['simulator']}** simulator (the tasks' MuJoCo Warp "
                "twins, float32), evaluated on CPU MuJoCo: each run is another draw of its "
                "algorithm than a CPU-trained one"
                + (f"; {', '.join(cpu)} (no twin) trained on CPU MuJoCo" if cpu else "")
            )
        lines += _beyond_the_paper(spec)
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
    lines += sources_lines(spec)
    lines += budgets
    if summary["missing"]:
        lines += ["## Missing cells", ""] + [f"- {m}" for m in summary["missing"]] + [""]
    lines += _normalisation_lines(summary)
    lines += ["## Static evaluation", ""]
    cells = [
        c
        for source in ("results", "reference_results")
        for by_algo in (summary.get(source) or {}).values()
        for metrics in by_algo.values()
        for c in metrics.values()
        if isinstance(c, dict)
    ]
    if any(few_seeds(c) for c in cells):
        lines += [FEW_SEEDS_NOTE, ""]
    if summary.get("unstable"):
        lines += [UNSTABLE_NOTE, ""]
    skipped = summary.get("tables_not_written") or {}
    if skipped:
        lines += ["Tables not written (they would have no row):", ""]
        lines += [f"- `tables/{name}.tex`: {why}" for name, why in skipped.items()] + [""]
    for name in ("raw_worst_case", "raw_average_case", "normalised_worst_case"):
        lines += md_table(summary, name, paper)
    lines += md_table(summary, "normalised_average_case", paper)
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
        "prints them in the paper's per-task units)."
        if "dynamic" not in skipped
        else f"No table: {skipped['dynamic']}.",
        "",
    ] + md_table(summary, "dynamic", paper)
    poi = [
        (a, v["poi_over_td3_worst_case"])
        for a, v in summary["aggregate"].items()
        if "poi_over_td3_worst_case" in v
    ]
    if poi:
        zero = normaliser_names()[0]
        lines += [
            f"## Probability of improvement over {zero} (worst case)",
            "",
            f"| algorithm | P(better than {zero}) | 95% CI | tasks |",
            "|---|---|---|---|",
        ]
        for algo, p in poi:
            ci = p.get("ci95")
            ci_text = f"[{fmt(ci[0])}, {fmt(ci[1])}]" if ci else "–"
            value = fmt(p["value"]) + (FEW if 0 < (p.get("min_seeds") or 3) < 3 else "")
            lines.append(f"| {label(summary, algo)} | {value} | {ci_text} | {p['n_tasks']} |")
        lines.append("")
    lines += rechecked_markdown(summary, lambda a: label(summary, a))
    lines += pairwise_markdown(summary, lambda a: label(summary, a))
    lines += reference_lines(summary)
    lines += submitted_lines(summary)
    if figures:
        lines += ["## Figures", "", "Each figure is also a vector PDF beside its PNG.", ""]
        for caption, path in figures:
            lines += [f"**{caption}**", "", f"![{caption}]({path.relative_to(out).as_posix()})", ""]
    lines += ["## Conventions", ""]
    lines += [f"- **{k}**: {v}" for k, v in summary["conventions"].items()]
    lines += [
        "",
        "Tables for papers: `tables/<name>.tex` (a booktabs `tabular`, scaled down to the line "
        "only when wider: needs `booktabs` and `graphicx`; cells "
        + ("`mean ± std`" if summary.get("table_cells") == "pm" else "`mean [95% CI]`")
        + " (`rrls report --cells`); its header holds the suggested caption with every note: "
        "`\\input` it inside your own `table`) and `tables/<name>.csv`.",
        "",
    ]
    return "\n".join(lines)


def _counts(summary: dict[str, Any]) -> str:
    """What the report holds, counted from its finished runs rather than what the preset
    plans: ``2 algorithms trained here × 1 task × 3 seeds, 1 submitted × 1 task × 2 seeds``."""
    spec, done = summary.get("benchmark") or {}, summary.get("finished_runs") or {}

    def count(n: int, word: str) -> str:
        return f"{n} {word}{'' if n == 1 else 's'}"

    parts = [
        f"{count(len(held['algorithms']), 'algorithm')} {where} × "
        f"{count(len(held['tasks']), 'task')} × {count(len(held['seeds']), 'seed')}"
        for source, where in (("trained", "trained here"), ("submitted", "submitted"))
        if (held := done.get(source))
    ]
    trained = done.get("trained") or {}
    if spec.get("by_task"):  # joined benchmarks: seeds differ by task (Sources)
        return f"{trained.get('runs', 0)} runs trained there" + (
            f", {parts[1]}" if len(parts) > 1 else ""
        )
    planned = [len(spec.get(k) or []) for k in ("algos", "tasks", "seeds")]
    if planned[0] and planned != [
        len(trained.get(k) or []) for k in ("algorithms", "tasks", "seeds")
    ]:
        parts.append(f"the protocol plans {' × '.join(map(str, planned))} trained runs")
    return ", ".join(parts) or "no finished run"


def _normalisation_lines(summary: dict[str, Any]) -> list[str]:
    """Which TD3 / M2TD3 means normalise each task: the benchmark's, a reference's, or none."""
    ref = summary.get("reference")
    sources: dict[str, list[str]] = {}
    for task in summary["tasks"]:
        used = {v for v in summary.get("normalisation", {}).get(task, {}).values()}
        key = "reference" if "reference" in used else "benchmark" if "benchmark" in used else "-"
        sources.setdefault(key, []).append(task)
    lines = ["## Normalisation", ""]
    pair = " and ".join(normaliser_names())
    if sources.get("benchmark"):
        lines.append(f"- this benchmark's own {pair} runs: {', '.join(sources['benchmark'])}")
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
            f"- none (no finished {pair} runs here"
            + (" nor in the reference" if ref else "; `rrls report DIR --reference FILE`")
            + f"): {', '.join(sources['-'])}"
        )
    lines += unstable_normalisation(summary)
    return [*lines, ""]
