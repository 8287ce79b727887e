"""The report's sections on where its rows come from: each source's training budget (this
benchmark's runs, submitted policies, a reference), the reference's protocol and the submitted
policies' provenance. Apart from ``report.py`` so that the report reads as its tables."""

from __future__ import annotations

from typing import Any

from rrls.report.caveats import BUDGET, BUDGET_NOTE, budget_differs
from rrls.report.tables import label

__all__ = ["budget_lines", "reference_lines", "submitted_lines"]


def reference_lines(summary: dict[str, Any]) -> list[str]:
    """Where the reference's rows of the tables come from (its protocol and budget)."""
    ref = summary.get("reference")
    if not ref or not ref.get("rows"):
        return []
    return [
        f"## Reference: {ref['label']}",
        "",
        f"`{ref['file']}`: physics {ref['physics']}, set {summary['uncertainty']}, mesh "
        f"{ref['mesh']} x {ref['episodes']} episodes"
        + (f", {ref['steps']:,} training steps per run" if ref.get("steps") else "")
        + f". Its rows are labelled `(ref. {ref['name']})` (or as `--rename` names them) in "
        "every table above and in `tables/*.tex`; normalised with "
        + (
            "its own TD3 and M2TD3 means (its budget is not this benchmark's: its rows carry "
            f"{BUDGET}).",
            "this report's TD3 and M2TD3 means.",
        )[not str(ref.get("normalised_by", "")).startswith("its")],
        "",
    ]


def budget_lines(summary: dict[str, Any]) -> list[str]:
    """Each source's training budget beside the benchmark's: its own runs, every submitted
    algorithm (what its submitter declared, or its policy recorded), the reference."""
    spec = summary.get("benchmark") or {}
    own, submitted = spec.get("steps"), summary.get("submitted") or []
    ref = summary.get("reference") or {}
    if not submitted and not ref.get("rows"):
        return []

    def steps_text(steps: Any) -> str:
        return f"{steps:,}" if steps else "not stated"

    rows = []
    if spec.get("algos"):
        rows.append(("this benchmark's runs", steps_text(own), "", ""))
    by_algo: dict[str, list[dict[str, Any]]] = {}
    for run in submitted:
        by_algo.setdefault(run["algorithm"], []).append(run)
    differing = {a for a in by_algo if budget_differs(summary, a)}
    differing |= {a for a in summary.get("run_steps") or {} if budget_differs(summary, a)}
    for algo, runs in by_algo.items():
        values = sorted({r.get("steps") or 0 for r in runs})
        extra = sorted({f"{k} {v}" for r in runs for k, v in (r.get("budget") or {}).items()
                        if k not in ("steps", "declared_by") and v is not None})  # fmt: skip
        who = sorted({(r.get("budget") or {}).get("declared_by") or "nobody" for r in runs})
        differs = algo in differing
        rows.append(
            (
                label(summary, algo),
                ", ".join(steps_text(v) for v in values),
                "; ".join(extra),
                f"declared by {', '.join(who)}" + ("; **differs**" if differs else ""),
            )
        )
    for algo, steps in (summary.get("run_steps") or {}).items():
        if budget_differs(summary, algo):  # a run of this benchmark with other steps
            rows.append(
                (label(summary, algo), ", ".join(map(steps_text, steps)), "", "**differs**")
            )
    if ref.get("rows"):
        differs = bool(own) and ref.get("steps") != own
        rows.append(
            (
                f"reference {ref.get('name')}" + (BUDGET if differs else ""),
                steps_text(ref.get("steps")),
                "",
                "its file" + ("; **differs**" if differs else ""),
            )
        )
    lines = [
        "## Budgets",
        "",
        f"Training steps per run of each source; this benchmark's protocol: {steps_text(own)}.",
        "",
        "| source | training steps | other budget | note |",
        "|---|---|---|---|",
        *[f"| {a} | {b} | {c or '–'} | {d or '–'} |" for a, b, c, d in rows],
        "",
    ]
    if differing or (ref.get("rows") and budget_differs(summary, "", "reference_results")):
        lines += [BUDGET_NOTE, ""]
    return lines


def submitted_lines(summary: dict[str, Any]) -> list[str]:
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
            f"| {label(summary, r['algorithm'])} | {r['task']} | {r['seed']} "
            f"| {r.get('policy_kind') or '–'} "
            f"| `{r.get('policy_source') or '–'}` | {sha} |"
        )
    return [*lines, ""]
