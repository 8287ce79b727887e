"""Pairwise comparisons a reviewer expects: for every pair of algorithms on a task and a score,
the difference of the seed means with its 95 % Welch interval, the two-sided Welch p-value,
the Holm-corrected verdict over the whole family of pairs, and an effect size (Hedges' g).

Why not disjoint intervals alone: two 95 % Student-t intervals at 5 seeds are disjoint only
when the means differ by about 5.6 standard errors, while Welch's test resolves about 3.3; and
ten pairs tested at 5 % each find a false difference more often than 5 %. Holm's step-down
correction keeps the family's error at 5 % and is uniformly more powerful than Bonferroni.
The paper's orderings (its Tables 7-8 means) are then judged by the corrected test:
*reproduced* (significant, the paper's way), *contradicted* (significant, the other way) or
*unresolved*; an ordering the paper itself calls not significant is marked as such, and so is
one its own means and standard deviations (10 seeds) do not resolve by the same test.

>>> [round(p, 9) for p in holm([0.01, 0.04, 0.03])]
[0.03, 0.06, 0.06]
"""

from __future__ import annotations

import itertools
import math
import warnings
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from rrls.report.names import task_name

__all__ = [
    "ALPHA",
    "PAPER_NOT_SIGNIFICANT",
    "compare",
    "holm",
    "judge_paper",
    "pairwise",
]

#: the family-wise error rate of every verdict
ALPHA = 0.05
#: orderings the paper's text calls not statistically significant: (task, score, a, b).
#: Section 5: "M2TD3 [...] outperforms all baselines except on HalfCheetah where DR achieves a
#: slightly, non-statistically significant, better score" (the worst case, Table 4).
PAPER_NOT_SIGNIFICANT = (("halfcheetah", "worst_case", "dr", "m2td3"),)


def holm(pvalues: Sequence[float]) -> list[float]:
    """Holm-adjusted p-values (step-down, monotone, capped at 1), in the input's order."""
    p = np.asarray(pvalues, dtype=float)
    m = len(p)
    out = np.empty(m)
    running = 0.0
    for rank, i in enumerate(np.argsort(p, kind="stable")):
        running = max(running, min(1.0, (m - rank) * p[i]))
        out[i] = running
    return [float(v) for v in out]


def compare(x: Sequence[float], y: Sequence[float]) -> dict[str, Any]:
    """Welch's comparison of two seed samples: ``mean_x - mean_y`` with its 95 % interval, the
    two-sided p-value and Hedges' g (the pooled-std effect size, small-sample corrected).
    Fewer than two seeds on a side: no test (``p`` None)."""
    from scipy import stats

    a, b = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
    out: dict[str, Any] = {
        "n": [int(a.size), int(b.size)],
        "diff": float(a.mean() - b.mean()) if a.size and b.size else None,
        "ci95": None,
        "p": None,
        "hedges_g": None,
    }
    if a.size < 2 or b.size < 2:
        return out
    with warnings.catch_warnings():  # a constant sample (a policy that always falls) is fine
        warnings.simplefilter("ignore", RuntimeWarning)
        test = stats.ttest_ind(a, b, equal_var=False)
    if not np.isfinite(test.pvalue):  # both samples constant
        return out
    ci = test.confidence_interval(0.95)
    pooled = math.sqrt(
        ((a.size - 1) * a.var(ddof=1) + (b.size - 1) * b.var(ddof=1)) / (a.size + b.size - 2)
    )
    correction = 1 - 3 / (4 * (a.size + b.size) - 9)
    out.update(
        ci95=[float(ci.low), float(ci.high)],
        p=float(test.pvalue),
        hedges_g=None if pooled == 0 else float(out["diff"] / pooled * correction),
    )
    return out


def pairwise(values: Mapping[str, Sequence[float]], alpha: float = ALPHA) -> list[dict[str, Any]]:
    """Every pair of ``{algo: per-seed values}`` (in the mapping's order), compared by Welch
    and judged with Holm's correction over the pairs that could be tested: ``verdict`` is
    ``"a > b"``, ``"a < b"`` or ``"no difference shown"`` (``None``: too few seeds)."""
    rows = [
        {"a": a, "b": b, **compare(values[a], values[b])}
        for a, b in itertools.combinations(values, 2)
    ]
    tested = [r for r in rows if r["p"] is not None]
    for row, adjusted in zip(tested, holm([r["p"] for r in tested])):
        row["p_holm"] = adjusted
        if adjusted >= alpha:
            row["verdict"] = "no difference shown"
        else:
            row["verdict"] = (
                f"{row['a']} > {row['b']}" if row["diff"] > 0 else (f"{row['a']} < {row['b']}")
            )
    for row in rows:
        row.setdefault("p_holm", None)
        row.setdefault("verdict", None)
    return rows


def paper_p(paper: Mapping[str, Any], table: str, task: str, a: str, b: str) -> float | None:
    """The two-sided Welch p-value of the paper's own numbers (mean ± std over its seeds)."""
    from scipy import stats

    try:
        (ma, sa), (mb, sb) = paper[table][a][task], paper[table][b][task]
    except (KeyError, TypeError):
        return None
    n = int(paper.get("seeds", 10))
    return float(stats.ttest_ind_from_stats(ma, sa, n, mb, sb, n, equal_var=False).pvalue)


def judge_paper(
    rows: list[dict[str, Any]], paper: Mapping[str, Any], task: str, metric: str
) -> list[dict[str, Any]]:
    """Each tested pair beside the paper's ordering of it (``paper_results()``): the verdict
    ``reproduced`` / ``contradicted`` / ``unresolved`` by the Holm-corrected test, and whether
    the paper calls it not significant (its text) or its own numbers do not resolve it (Welch
    on its mean ± std over its seeds, Holm over the same pairs)."""
    table = f"raw_{metric}"
    out = []
    for row in rows:
        a, b = row["a"], row["b"]
        try:
            pa, pb = paper[table][a][task][0], paper[table][b][task][0]
        except (KeyError, TypeError):
            continue
        hi, lo = (a, b) if pa > pb else (b, a)
        out.append({"hi": hi, "lo": lo, "row": row, "paper_p": paper_p(paper, table, task, a, b)})
    for item, adjusted in zip(out, holm([i["paper_p"] or 1.0 for i in out])):
        row, hi, lo = item["row"], item["hi"], item["lo"]
        sign = 1 if row["a"] == hi else -1
        if row["p_holm"] is None or row["p_holm"] >= ALPHA:
            verdict = "unresolved"
        else:
            verdict = "reproduced" if sign * row["diff"] > 0 else "contradicted"
        said = {(task, metric, hi, lo), (task, metric, lo, hi)} & set(PAPER_NOT_SIGNIFICANT)
        item.update(
            verdict=verdict,
            paper_p_holm=adjusted,
            paper_says_not_significant=bool(said),
            paper_resolved=adjusted < ALPHA,
        )
    return out


#: the scores compared pairwise (raw: a normalised score is the same comparison rescaled)
METRICS = {"worst_case": "worst case", "average_case": "average case"}


def summarise_pairs(values: Any, tasks: Sequence[str], algos: Sequence[str]) -> dict[str, Any]:
    """``summary.json``'s ``pairwise``: per task and score, every pair's comparison.
    ``values(task, algo, metric)``: the per-seed values (``summary.Scores.values``)."""
    out: dict[str, Any] = {}
    for task in tasks:
        out[task] = {}
        for metric in METRICS:
            seeds = {a: values(task, a, metric) for a in algos}
            out[task][metric] = pairwise({a: v for a, v in seeds.items() if len(v)})
    return out


def paper_orderings(summary: Mapping[str, Any], paper: Mapping[str, Any]) -> dict[str, Any]:
    """Per task of the paper's (same set) and score: the paper's orderings judged here."""
    if summary.get("uncertainty") != paper.get("uncertainty"):
        return {}
    out: dict[str, Any] = {}
    for task, by_metric in (summary.get("pairwise") or {}).items():
        if task not in paper.get("tasks", ()):
            continue
        out[task] = {m: judge_paper(rows, paper, task, m) for m, rows in by_metric.items()}
    return out


def _num(x: float | None, digits: int = 1) -> str:
    return "–" if x is None else f"{x:.{digits}f}"


def _p(x: float | None) -> str:
    return "–" if x is None else ("< 0.001" if x < 0.001 else f"{x:.3f}")


def markdown(summary: Mapping[str, Any], name: Any = str) -> list[str]:
    """The report's section: a table per task and score, then the paper's orderings judged."""
    pairs = summary.get("pairwise") or {}
    if not any(rows for by in pairs.values() for rows in by.values()):
        return []
    lines = [
        "## Pairwise comparisons (Welch, Holm-corrected)",
        "",
        "Every pair of algorithms: the difference of seed means (first minus second) "
        "with its 95 % Welch interval, the two-sided Welch p-value, the same corrected by "
        f"Holm over the task's pairs (family-wise error {ALPHA:.0%}), the verdict at that "
        "level and Hedges' g (`tables/pairwise.csv`, `tables/pairwise_<score>.tex`).",
        "",
    ]
    for task, by_metric in pairs.items():
        for metric, rows in by_metric.items():
            if not rows:
                continue
            lines += [
                f"**{task_name(task)}, {METRICS[metric]}**",
                "",
                "| pair | difference [95 % CI] | p | p (Holm) | verdict | Hedges' g |",
                "|---|---|---|---|---|---|",
            ]
            for r in rows:
                ci = r["ci95"] and f" [{_num(r['ci95'][0])}, {_num(r['ci95'][1])}]"
                verdict = r["verdict"] or "too few seeds"
                for algo in (r["a"], r["b"]):
                    verdict = verdict.replace(algo, name(algo))
                lines.append(
                    f"| {name(r['a'])} − {name(r['b'])} | {_num(r['diff'])}{ci or ''} | "
                    f"{_p(r['p'])} | {_p(r['p_holm'])} | {verdict} | {_num(r['hedges_g'], 2)} |"
                )
            lines.append("")
    for task, by_metric in (summary.get("paper_orderings") or {}).items():
        for metric, judged in by_metric.items():
            counts = {k: [] for k in ("reproduced", "contradicted", "unresolved")}
            for j in judged:
                mark = (
                    " (the paper: not significant)"
                    if j["paper_says_not_significant"]
                    else (
                        "" if j["paper_resolved"] else " (not resolved by the paper's own numbers)"
                    )
                )
                counts[j["verdict"]].append(f"{name(j['hi'])} > {name(j['lo'])}{mark}")
            text = "; ".join(f"{k} {len(v)}: {', '.join(v) or 'none'}" for k, v in counts.items())
            lines.append(
                f"- **{task_name(task)}, {METRICS[metric]}**, the paper's orderings (its 5 M-step "
                f"means): {text}."
            )
    return [*lines, ""] if lines[-1] else lines


def write_tables(summary: Mapping[str, Any], out: Any, name: Any = str) -> None:
    """``tables/pairwise.csv`` (every pair, every task and score) and one ``.tex`` per score
    (booktabs; the notes in the caption's suggested text, outside the tabular)."""
    import pandas as pd

    from rrls.files import atomic_write_bytes, atomic_write_table

    pairs = summary.get("pairwise") or {}
    records = [
        {"task": t, "metric": m, "label_a": name(r["a"]), "label_b": name(r["b"]),
         **{k: v for k, v in r.items() if k != "ci95" and k != "n"},
         "n_a": r["n"][0], "n_b": r["n"][1],
         "ci95_low": (r["ci95"] or [None, None])[0], "ci95_high": (r["ci95"] or [None, None])[1]}
        for t, by in pairs.items() for m, rows in by.items() for r in rows
    ]  # fmt: skip
    if not records:
        return
    atomic_write_table(out / "pairwise.csv", pd.DataFrame(records))
    from rrls.report.tables import tex_escape

    for metric, title in METRICS.items():
        rows = [(t, r) for t, by in pairs.items() for r in by.get(metric, [])]
        if not rows:
            continue
        tex = [
            f"% Pairwise comparisons, {title}: Welch 95 % interval of the difference of means, "
            "two-sided p, Holm-corrected p -- generated by `rrls report`",
            "% needs \\usepackage{booktabs} and \\usepackage{graphicx}",
            "% the table's notes are its suggested caption; in a paper:",
            "% \\begin{table}[tbp]",
            "% \\centering",
            f"% \\caption{{Pairwise comparisons of the {title} over seeds: difference of means "
            "(first minus second) with its 95\\% Welch interval, two-sided Welch $p$-value and "
            f"Holm-corrected $p$-value (family-wise error {ALPHA * 100:g}\\% per task over its "
            "pairs); $^{*}$: a difference the corrected test resolves.}",
            f"% \\label{{tab:rrls-pairwise_{metric}}}",
            f"% \\input{{pairwise_{metric}}}",
            "% \\end{table}",
            "\\begin{tabular}{llrrrr}",
            "\\toprule",
            "Task & Pair & Difference & 95\\% CI & $p$ & $p_{\\mathrm{Holm}}$ \\\\",
            "\\midrule",
        ]
        for task, r in rows:
            ci = r["ci95"] and f"[{_num(r['ci95'][0])}, {_num(r['ci95'][1])}]"
            star = "$^{*}$" if r["p_holm"] is not None and r["p_holm"] < ALPHA else ""
            pair = tex_escape(f"{name(r['a'])} - {name(r['b'])}")
            tex.append(
                f"{tex_escape(task_name(task))} & {pair} & ${_num(r['diff'])}${star} & "
                f"${ci or '--'}$ & {_p(r['p']).replace('<', '$<$')} & "
                f"{_p(r['p_holm']).replace('<', '$<$')} \\\\"
            )
        tex += ["\\bottomrule", "\\end{tabular}", ""]
        atomic_write_bytes(out / f"pairwise_{metric}.tex", "\n".join(tex).encode())
