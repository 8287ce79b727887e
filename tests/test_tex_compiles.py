"""A report's tables go into a paper unedited: every ``.tex`` it writes compiles with pdflatex in
a plain ``article`` loading only the packages the docs name (``rrls.report.latex.PACKAGES``),
inside the float its header suggests, with no error and no overfull line; every row trained with
another budget than the benchmark's carries ‡ whatever ``--rename`` calls it, in every table;
a reference of another budget is refused unless asked for, then marked, normalised by its own
baselines and never bold. Skipped only where no TeX engine is installed and ``CI`` is unset
(``.ci/run`` installs one).

The benchmark is the smoke protocol with fixed linear controllers as its TD3 and M2TD3 runs
(``tests/test_submit.py``), a submitted method declaring 200 steps where the benchmark's runs
trained 300, renamed, and a reference that trained 3 000.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from test_submit import linear, make_benchmark

from rrls.benchmark.store import build_store
from rrls.cli import main
from rrls.report.cells import average, tied_best
from rrls.report.exported import export_reference
from rrls.report.latex import PACKAGES
from rrls.report.tables import label, table_rows
from rrls.report.writer import make_report
from rrls.submissions.steps import create_benchmark, submit

pytest.importorskip("scipy")

ROOT = Path(__file__).resolve().parents[1]
RENAMED = "SAC-DR (ours)"
MARK = "$^{\\ddagger}$"


def wide_store(root: Path) -> Path:
    """A store of the paper's five algorithms on its five tasks, 3 seeds, returns in the
    tasks' magnitudes: a table as wide as the paper's."""
    rng = np.random.default_rng(0)
    scale = {"ant": 3e3, "halfcheetah": 3e3, "hopper": 1e3, "humanoidstandup": 1e5, "walker": 3e3}
    rows, runs = [], []
    for task, size in scale.items():
        for i, algo in enumerate(["td3", "dr", "rarl", "nrmdp", "m2td3"]):
            for seed in range(3):
                key = dict(algorithm=algo, task=task, uncertainty="3d", seed=seed, steps=10)
                runs.append(key)
                for point in range(3):
                    value = size * (0.2 * i + rng.uniform(0, 0.3) + 0.1 * point)
                    rows.append({**key, "point": point, "episode": 0, "return": value})
    results = root / "results"
    results.mkdir(parents=True)
    pd.DataFrame(rows).to_csv(results / "evaluations.csv", index=False)
    pd.DataFrame(runs).to_csv(results / "runs.csv", index=False)
    for name, cols in (("dynamic", ["algorithm", "task", "seed", "episode", "return"]),
                       ("curves", ["algorithm", "task", "seed", "step"])):  # fmt: skip
        pd.DataFrame(columns=cols).to_csv(results / f"{name}.csv", index=False)
    return root


def engine() -> str:
    """pdflatex, or a skip where there is none and this is not CI (there: a failure)."""
    found = shutil.which("pdflatex")
    if found:
        return found
    if os.environ.get("CI"):
        pytest.fail("pdflatex missing in CI: .ci/run installs texlive-latex-base")
    pytest.skip("no TeX engine (pdflatex); .ci/run installs one")


@pytest.fixture(scope="module")
def bench(tmp_path_factory) -> Path:
    """The smoke benchmark, ``my-sac`` submitted at 3 seeds with 200 steps declared, and
    ``other.json``: its own results as a reference that trained 3 000 steps."""
    tmp = tmp_path_factory.mktemp("tex")
    root = make_benchmark(tmp / "bench")
    for seed in range(3):
        policy = linear(0.0, 4.0 + seed, 0.0, 0.5)
        submit(root, "my-sac", "invertedpendulum", seed, policy, workers=1, steps=200)
    build_store(root)
    make_report(root, plots=False)
    export_reference(root, tmp / "ref.json", label="lab B")
    data = json.loads((tmp / "ref.json").read_text())
    (tmp / "other.json").write_text(json.dumps({**data, "steps": 3000}))
    return root


def report(root: Path, *extra: str) -> Path:
    argv = ["report", str(root), "--no-plots", "--reference", str(root.parent / "other.json")]
    assert main([*argv, "--rename", f"my-sac={RENAMED}", "--allow-other-budget", *extra]) == 0
    return root / "report"


def compile_table(tex: Path, build: Path) -> tuple[str, float]:
    """pdflatex's log of ``tex`` inside the float its header suggests (a bare ``\\input``
    without one), and the table's natural width over the line's."""
    build.mkdir(parents=True, exist_ok=True)
    shutil.copy(tex, build / tex.name)
    header = [line[2:] for line in tex.read_text().splitlines() if line.startswith("% ")]
    measure = "\\typeout{RRLSFIT \\the\\wd\\rrlsfit\\space\\the\\linewidth}"
    body = f"\\input{{{tex.stem}}}"
    if "\\begin{table}[tbp]" in header:
        float_ = header[header.index("\\begin{table}[tbp]") : header.index("\\end{table}") + 1]
        body = "\n".join(float_)
    assert f"\\input{{{tex.stem}}}" in body, tex.name
    body = body.replace(f"\\input{{{tex.stem}}}", f"\\input{{{tex.stem}}}{measure}")
    preamble = "".join(f"\\usepackage{{{p}}}\n" for p in PACKAGES)
    doc = f"\\documentclass{{article}}\n{preamble}\\begin{{document}}\n{body}\n\\end{{document}}\n"
    (build / f"doc-{tex.stem}.tex").write_text(doc)
    proc = subprocess.run(
        [engine(), "-interaction=nonstopmode", "-halt-on-error", f"doc-{tex.stem}.tex"],
        cwd=build,
        capture_output=True,
        timeout=120,
    )
    log = (build / f"doc-{tex.stem}.log").read_text(errors="replace")
    assert proc.returncode == 0 and "\n! " not in log, f"{tex.name}: {log[-1500:]}"
    width, line = re.search(r"RRLSFIT ([\d.]+)pt ([\d.]+)pt", log).groups()
    return log, float(width) / float(line)


def test_the_docs_name_the_packages_every_table_needs():
    text = (ROOT / "docs" / "benchmark.md").read_text()
    for package in PACKAGES:
        assert f"`{package}`" in text, package


@pytest.mark.parametrize("cells", ["ci", "pm"])
def test_every_tex_compiles_in_a_plain_article_without_overfull_lines(bench, tmp_path, cells):
    engine()
    tables = report(bench, "--cells", cells) / "tables"
    written = sorted(tables.glob("*.tex"))
    names = {p.stem for p in written}
    assert {"raw_worst_case", "normalised_worst_case", "pairwise_worst_case"} <= names
    for tex in written:
        log, _ = compile_table(tex, tmp_path / "build")
        assert "Overfull \\hbox" not in log, f"{tex.name}: {log[log.index('Overfull') :][:300]}"
        text = tex.read_text()
        rows = [line for line in text.splitlines() if not line.startswith("%")]
        # the renamed submission and every reference row: trained with another budget
        marked = [line for line in rows if RENAMED in line or "(ref. " in line]
        assert marked, tex.name
        assert all(f"{RENAMED}{MARK}" in line or f"other){MARK}" in line for line in marked), (
            tex.name
        )
        if not tex.stem.startswith("pairwise"):
            assert f"{MARK} another training budget" in text, tex.name  # said in the caption
            assert "\\multicolumn" not in text  # no note inside the tabular
            # never bold: a row of another budget is not ranked
            assert not any("mathbf" in line for line in marked), tex.name
            cell = "\\pm" if cells == "pm" else "\\,["
            assert cell in text and ("\\,[" if cells == "pm" else "\\pm") not in "".join(rows)


def test_a_wide_table_is_scaled_to_the_line_and_a_narrow_one_kept(bench, tmp_path):
    engine()
    make_report(wide_store(tmp_path / "paper"), plots=False)  # 5 tasks × mean [95 % CI]
    wide = tmp_path / "paper" / "report" / "tables" / "normalised_worst_case.tex"
    log, ratio = compile_table(wide, tmp_path / "build")
    assert ratio > 1 and "Overfull \\hbox" not in log  # scaled down, not overflowing
    narrow = report(bench) / "tables" / "raw_worst_case.tex"
    log, ratio = compile_table(narrow, tmp_path / "build")
    assert ratio < 1 and "Overfull \\hbox" not in log  # its own size: never scaled up


def test_a_reference_of_another_budget_is_refused_in_one_line(bench, capsys):
    other = str(bench.parent / "other.json")
    assert main(["report", str(bench), "--no-plots", "--reference", other]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1
    assert "3,000 training steps per run, this benchmark 300" in err
    assert "--allow-other-budget" in err


def test_a_rename_keeps_the_mark_in_every_section_csv_and_figure_label(bench):
    out = report(bench)
    summary = json.loads((out / "summary.json").read_text())
    assert label(summary, "my-sac") == f"{RENAMED}‡"  # what the figures call the row
    assert label(summary, "td3") == "TD3"
    assert label(summary, "td3", "reference_results") == "TD3 (ref. other)‡"
    md = (out / "report.md").read_text()
    sections = {s.split("\n", 1)[0]: s for s in md.split("\n## ")}
    for title in ("Budgets", "Per run", "Submitted policies"):
        assert f"| {RENAMED}‡ |" in sections[title], title
        assert "my-sac" not in sections[title].replace("`", ""), title
    assert "| reference other‡ | 3,000 |" in sections["Budgets"]
    # the reference's rows are named as the report says they are
    assert "labelled `(ref. other)`" in md and "TD3 (ref. other)‡" in md
    raw = pd.read_csv(out / "tables" / "raw_worst_case.csv")
    mine = raw[(raw["algorithm"] == "my-sac") & (raw["source"] == "benchmark")]
    assert set(mine["label"]) == {f"{RENAMED}‡"} and mine["other_budget"].all()
    # each run's training budget: 300 here, 200 declared by the submitter
    runs = pd.read_csv(out / "tables" / "per_run.csv")
    steps = dict(zip(runs["algorithm"], runs["steps"]))
    assert steps == {"td3": 300, "m2td3": 300, "my-sac": 200}
    assert set(runs[runs["algorithm"] == "my-sac"]["label"]) == {f"{RENAMED}‡"}


def test_a_reference_of_another_budget_is_normalised_by_its_own_baselines(bench):
    out = report(bench)
    summary = json.loads((out / "summary.json").read_text())
    assert summary["reference"]["normalised_by"] == "its own TD3 and M2TD3"
    theirs = summary["reference_results"]["invertedpendulum"]
    # its TD3 and M2TD3 are 0 and 1 by construction; not this benchmark's normalisers'
    assert theirs["td3"]["normalised"]["worst_case"]["mean"] == pytest.approx(0.0)
    assert theirs["m2td3"]["normalised"]["worst_case"]["mean"] == pytest.approx(1.0)
    names = [r[0] for r in table_rows(summary, "normalised_worst_case")]
    assert names[:3] == ["TD3", "M2TD3", f"{RENAMED}‡"] and all(
        n.endswith("(ref. other)‡") for n in names[3:]
    )


def test_the_header_counts_the_runs_that_finished(tmp_path):
    root = tmp_path / "mine"
    create_benchmark(root, "smoke", ("invertedpendulum",))
    for seed in range(2):
        submit(root, "mine", "invertedpendulum", seed, linear(0, 5 + seed, 0, 1), workers=1)
    build_store(root)
    head = make_report(root, plots=False).read_text().splitlines()[2]
    assert "1 algorithm submitted × 1 task × 2 seeds" in head and "built-in" not in head


def test_rows_follow_the_papers_order_in_raw_and_normalised_tables(tmp_path):
    make_report(wide_store(tmp_path), plots=False)
    order = ["TD3", "DR", "M2TD3", "RARL", "NR-MDP"]  # the paper's Tables 4-5
    for name in ("raw_worst_case", "raw_average_case", "normalised_worst_case"):
        text = (tmp_path / "report" / "tables" / f"{name}.tex").read_text()
        rows = [line.split(" & ")[0] for line in text.splitlines() if " & " in line]
        assert rows[1:] == order, name  # after the heading


def test_bold_marks_every_row_whose_interval_overlaps_the_best():
    best = {"mean": 10.0, "ci95": [8.0, 12.0]}
    tie = {"mean": 7.0, "ci95": [5.0, 8.5]}
    apart = {"mean": 7.0, "ci95": [6.0, 7.9]}
    point = {"mean": 9.0, "ci95": None}  # one seed: its mean, inside the best's interval
    assert tied_best([apart, best, tie, point, None]) == [False, True, True, True, False]


def test_the_average_interval_combines_the_tasks_standard_errors():
    from scipy.stats import t

    rng = np.random.default_rng(0)
    x, y = rng.normal(0, 1, 3), rng.normal(2, 3, 5)

    def cell(v):
        half = t.ppf(0.975, len(v) - 1) * v.std(ddof=1) / np.sqrt(len(v))
        return {
            "mean": v.mean(),
            "std": v.std(),
            "n_seeds": len(v),
            "ci95": [v.mean() - half, v.mean() + half],
        }

    one = average([cell(x)])  # one task: that task's interval
    np.testing.assert_allclose(one["ci95"], cell(x)["ci95"])
    both = average([cell(x), cell(y)])
    va, vb = x.var(ddof=1) / 3, y.var(ddof=1) / 5
    df = (va + vb) ** 2 / (va**2 / 2 + vb**2 / 4)  # Welch-Satterthwaite
    half = t.ppf(0.975, df) * np.sqrt(va + vb) / 2
    mean = (x.mean() + y.mean()) / 2
    np.testing.assert_allclose(both["ci95"], [mean - half, mean + half])
    assert both["std"] == pytest.approx((x.std() + y.std()) / 2)  # the paper's ± column
    assert average([cell(x), {"mean": 1.0, "std": None, "n_seeds": 1}])["ci95"] is None
