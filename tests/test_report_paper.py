"""A comparison ready for a paper: every .tex table carries the reference's rows and a 95 % CI,
the caveats travel with the cells, empty tables are not written, the scores have one
definition, and the figures follow rliable's definitions in a colour-blind-safe style."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from rrls.evaluation.metrics import run_scores, scores_of, split_run_scores
from rrls.report import profiles, stats
from rrls.report.figstyle import PALETTE, colours
from rrls.report.reference import Reference
from rrls.report.tables import write_tables
from rrls.report.writer import make_report, paper_results, summarise, terminal_table

# per algorithm: per seed, the returns at the set's 3 mesh points (polemass 1, 16, 31)
RETURNS = {
    "td3": [[10.0, 20.0, 30.0], [14.0, 22.0, 30.0], [12.0, 25.0, 30.0]],
    "m2td3": [[40.0, 50.0, 60.0], [44.0, 52.0, 60.0], [42.0, 55.0, 60.0]],
    "dr": [[20.0, 30.0, 40.0], [24.0, 31.0, 40.0]],  # two seeds
    "rarl": [[25.0, 30.0, 35.0]],  # one seed
}
REFERENCE_ROWS = [
    {"task": "invertedpendulum", "uncertainty": "1d", "algorithm": algo, "metric": metric}
    | {"mean": float(np.mean(v)), "std": float(np.std(v)), "n_seeds": 3, "values": v}
    for algo, metric, v in [
        ("td3", "worst_case", [5.0, 6.0, 7.0]),
        ("td3", "average_case", [9.0, 10.0, 11.0]),
        ("m2td3", "worst_case", [20.0, 22.0, 24.0]),
        ("m2td3", "average_case", [30.0, 31.0, 32.0]),
    ]
]


def _store(root, returns=RETURNS, dynamic=False):
    rows, runs = [], []
    for algo, seeds in returns.items():
        for seed, rets in enumerate(seeds):
            key = dict(algorithm=algo, task="invertedpendulum", uncertainty="1d", seed=seed)
            runs.append({**key, "steps": 10})
            for point, (mass, ret) in enumerate(zip((1.0, 16.0, 31.0), rets)):
                for episode, noise in enumerate((-1.0, 1.0)):
                    rows.append(
                        {**key, "steps": 10, "point": point, "polemass": mass}
                        | {
                            "episode": episode,
                            "return": ret + noise,
                        }
                    )
    results = root / "results"
    results.mkdir(parents=True)
    pd.DataFrame(rows).to_csv(results / "evaluations.csv", index=False)
    dyn = [dict(algorithm="rarl", task="invertedpendulum", seed=0, episode=0, **{"return": 7.0})]
    cols = ["algorithm", "task", "seed", "episode", "return"]
    (pd.DataFrame(dyn) if dynamic else pd.DataFrame(columns=cols)).to_csv(
        results / "dynamic.csv", index=False
    )
    pd.DataFrame(runs).to_csv(results / "runs.csv", index=False)
    pd.DataFrame(columns=["algorithm", "task", "seed", "step"]).to_csv(
        results / "curves.csv", index=False
    )
    return root


def _reference():
    return Reference(
        label="lab A",
        physics="rrls-v5",
        mesh=3,
        episodes=2,
        rows=REFERENCE_ROWS,
        path="/somewhere/lab-a.json",
    )


def test_every_tex_table_carries_the_references_rows_and_a_ci(tmp_path):
    root = _store(tmp_path)
    summary = summarise(root, _reference())
    written, skipped = write_tables(summary, root / "tables", paper_results())
    tex = (root / "tables" / "raw_worst_case.tex").read_text()
    assert "\\begin{tabular}" in tex and "\\begin{table}\n" not in tex  # \input-able
    assert tex.index("\\toprule") < tex.index("\\midrule") < tex.index("\\bottomrule")
    # the reference, named, with its CI: Student t over 5, 6, 7 (6 ± 4.303 · 1 / sqrt(3))
    assert "TD3 (ref. lab-a) & $6.00\\,[3.52, 8.48]$" in tex
    td3 = summary["results"]["invertedpendulum"]["td3"]["worst_case"]
    lo, hi = (f"{v:.2f}" for v in td3["ci95"])
    assert f"TD3 & $12.00\\,[{lo}, {hi}]$" in tex
    assert "\\mathbf{42.00}" in tex  # the best own mean of the column
    write_tables(summary, root / "pm", paper_results(), cells="pm")
    std = (root / "pm" / "raw_worst_case.tex").read_text()
    assert "TD3 & $12.00 \\pm 1.63$" in std and "TD3 (ref. lab-a) & $6.00 \\pm 0.82$" in std
    # the reference's rows normalised with this benchmark's TD3 and M2TD3 means
    norm = (root / "tables" / "normalised_worst_case.tex").read_text()
    assert "TD3 (ref. lab-a) & $-0.20" in norm  # (6 - 12) / |42 - 12|
    csv = pd.read_csv(root / "tables" / "raw_worst_case.csv")
    assert set(csv["source"]) == {"benchmark", "lab-a"}
    # no run against its own adversary: no empty Table 6, and the reason is recorded
    assert "dynamic" in skipped and not (root / "tables" / "dynamic.tex").exists()
    assert all(p.exists() for p in written)


def test_empty_tables_are_not_written_and_the_report_says_why(tmp_path):
    root = _store(tmp_path)
    make_report(root, plots=False)
    assert not (root / "report" / "tables" / "dynamic.tex").exists()
    md = (root / "report" / "report.md").read_text()
    assert "`tables/dynamic.tex`: no run was evaluated against its own adversary" in md
    summary = json.loads((root / "report" / "summary.json").read_text())
    assert set(summary["tables_not_written"]) == {"dynamic"}


def test_a_dynamic_table_with_rows_is_written(tmp_path):
    root = _store(tmp_path, dynamic=True)
    make_report(root, plots=False)
    tex = (root / "report" / "tables" / "dynamic.tex").read_text()
    assert "RARL & $7.00^{\\dagger}$" in tex  # one seed: its value alone, marked


def test_the_terminal_table_shows_the_reference_rows(tmp_path):
    summary = summarise(_store(tmp_path), _reference())
    text = terminal_table(summary)
    assert "TD3 (ref. lab-a)" in text and "M2TD3 (ref. lab-a)" in text
    rarl = next(line for line in text.splitlines() if line.split()[1:2] == ["RARL"])
    assert "±" not in rarl and "†" in rarl  # one seed: no "± 0.0"


def test_few_seeds_are_marked_in_tex_and_one_seed_never_shows_a_zero_spread(tmp_path):
    root = _store(tmp_path)
    make_report(root, plots=False)
    tables = root / "report" / "tables"
    raw = (tables / "raw_worst_case.tex").read_text()
    # DR's interval overlaps M2TD3's, the best: a tie, bold too
    assert "DR & $\\mathbf{22.00}\\,[" in raw and "]^{\\dagger}$" in raw
    assert "RARL & $25.00^{\\dagger}$" in raw  # one seed: no interval
    summary = json.loads((root / "report" / "summary.json").read_text())
    write_tables(summary, tmp_path / "pm", paper_results(), cells="pm")
    assert "RARL & $25.00^{\\dagger}$" in (tmp_path / "pm" / "raw_worst_case.tex").read_text()
    assert "not a confidence interval" in raw  # the note under the table, visible in a paper
    everything = "".join(p.read_text() for p in tables.glob("*.tex"))
    everything += (root / "report" / "report.md").read_text()
    assert "\\pm 0.00" not in everything and "± 0.00" not in everything
    section = everything.split("## Probability of improvement")[1]
    rows = [line.split("|") for line in section.splitlines()[4:7]]
    poi = {row[1].strip(): row[2].strip() for row in rows}  # the few-seeds mark on the value
    assert poi["DR"].endswith("†") and poi["RARL"].endswith("†")
    assert not poi["M2TD3"].endswith("†")
    assert "fewer than 3 seeds" in (root / "report" / "report.md").read_text()


def test_an_unstable_normalisation_is_flagged_wherever_the_score_appears(tmp_path):
    noisy = {
        "td3": [[10.0, 20.0, 30.0], [30.0, 40.0, 50.0], [20.0, 30.0, 40.0]],
        "m2td3": [[12.0, 20.0, 30.0], [33.0, 40.0, 50.0], [21.0, 30.0, 40.0]],
        "dr": [[15.0, 20.0, 30.0], [16.0, 20.0, 30.0], [17.0, 20.0, 30.0]],
    }
    root = _store(tmp_path, returns=noisy)
    make_report(root, plots=False)
    summary = json.loads((root / "report" / "summary.json").read_text())
    flagged = {(u["task"], u["metric"]) for u in summary["unstable"]}
    assert ("invertedpendulum", "worst_case") in flagged
    tex = (root / "report" / "tables" / "normalised_worst_case.tex").read_text()
    assert "\\S}$" in tex and "unstable normalisation" in tex
    csv = pd.read_csv(root / "report" / "tables" / "normalised_worst_case.csv")
    assert csv["unstable_normalisation"].all()
    raw = (root / "report" / "tables" / "raw_worst_case.tex").read_text()
    assert "\\S" not in raw  # raw scores do not divide by anything
    md = (root / "report" / "report.md").read_text()
    assert "§ **unstable normalisation**, invertedpendulum worst case" in md
    row = next(line for line in md.splitlines() if line.startswith("| DR |") and "§" in line)
    assert row


def test_a_reference_normalisation_is_checked_too(tmp_path):
    only_mine = {"dr": [[15.0, 20.0, 30.0], [16.0, 20.0, 30.0], [17.0, 20.0, 30.0]]}
    close = [dict(r) for r in REFERENCE_ROWS]
    close[2] |= {"mean": 6.5, "std": 3.0, "values": None}  # M2TD3 within TD3's noise
    ref = Reference(label="lab B", physics="rrls-v5", mesh=3, episodes=2, rows=close)
    summary = summarise(_store(tmp_path, returns=only_mine), ref)
    assert summary["normalisation"]["invertedpendulum"]["worst_case"] == "reference"
    assert [(u["metric"], u["source"]) for u in summary["unstable"]] == [
        ("worst_case", "reference")
    ]


def test_the_scores_have_one_definition(tmp_path):
    root = _store(tmp_path)
    ev = pd.read_csv(root / "results" / "evaluations.csv")
    table = run_scores(ev).set_index(["algorithm", "seed"])
    assert (
        table.loc[("td3", 0), "worst_case"] == 10.0
        and table.loc[("td3", 0), "average_case"] == 20.0
    )
    run = ev[(ev["algorithm"] == "td3") & (ev["seed"] == 1)]
    means = run.groupby("point")["return"].mean()
    assert scores_of(means) == {"worst_case": 14.0, "average_case": 22.0}
    assert stats.per_seed_scores(ev).equals(run_scores(ev))
    split = split_run_scores(ev.assign(in_distribution=ev["point"] < 2)).set_index(
        ["algorithm", "seed"]
    )
    assert split.loc[("td3", 0), "worst_case_ood"] == 30.0
    assert split.loc[("td3", 0), "average_case_id"] == 15.0
    assert stats.normalise(np.array([27.0]), 12.0, 42.0)[0] == pytest.approx(0.5)
    with pytest.raises(ValueError, match="undefined"):
        stats.normalise(np.array([1.0]), 2.0, 2.0)


def test_performance_profiles_and_pairs_follow_rliable():
    scores = [np.array([0.0, 0.5, 1.0]), np.array([2.0, 3.0, 4.0])]
    grid = np.array([-1.0, 0.25, 2.5, 10.0])
    prof = profiles.performance_profile(scores, grid, np.random.default_rng(0))
    assert prof["profile"].tolist() == [1.0, 5 / 6, 2 / 6, 0.0]
    assert np.all(prof["low"] <= prof["profile"]) and np.all(prof["profile"] <= prof["high"])
    two = profiles.performance_profile([np.array([0.0, 1.0])], grid, np.random.default_rng(0))
    assert two["low"] is None  # no band from two seeds
    per_seed = {
        "td3": {"t": np.array([1.0, 2.0])},
        "m2td3": {"t": np.array([3.0, 4.0])},
        "dr": {"t": np.array([2.0, 5.0])},
    }
    pairs = {(p["x"], p["y"]): p["value"] for p in profiles.poi_pairs(per_seed)}
    assert pairs[("m2td3", "td3")] == 1.0 and pairs[("dr", "td3")] == pytest.approx(0.875)
    assert ("td3", "m2td3") not in pairs  # 1 - P(M2TD3 > TD3): not repeated
    assert pairs[("dr", "m2td3")] == 0.5


def test_the_palette_never_repeats_for_ten_or_more_algorithms():
    algos = ["td3", "dr", "m2td3", "rarl", "nrmdp", "sac", "sacdr", *[f"mine{i}" for i in range(8)]]
    picked = colours(algos)
    assert len(set(picked.values())) == len(algos) == 15
    assert colours(["td3", "zzz"])["td3"] == colours(algos)["td3"] == PALETTE[0]  # stable
    assert "#1f77b4" not in picked.values()  # not matplotlib's tab10


@pytest.mark.e2e
def test_figures_are_bounded_by_the_set_and_written_as_pdf_too(tmp_path):
    pytest.importorskip("matplotlib")
    from rrls.report.plots import set_bounds

    root = _store(tmp_path)
    ev = pd.read_csv(root / "results" / "evaluations.csv")
    assert set_bounds("invertedpendulum", "1d", ev, "polemass") == (1.0, 31.0)
    assert set_bounds("invertedpendulum", "mine", ev.assign(polemass=2.0), "polemass") == (2.0, 2.0)
    make_report(root, plots=True)
    figures = root / "report" / "figures"
    for name in (
        "returns_invertedpendulum",
        "performance_profiles",
        "iqm",
        "probability_of_improvement",
    ):
        assert (figures / f"{name}.png").stat().st_size > 5_000
        assert (figures / f"{name}.pdf").read_bytes()[:4] == b"%PDF"
    md = (root / "report" / "report.md").read_text()
    assert "Performance profiles" in md and "fewer than 3 seeds" in md


def test_heatmaps_draw_every_mesh_point_as_a_full_cell_and_outline_the_set(tmp_path):
    from rrls.evaluation.result_plot import cell_edges
    from rrls.report import plots
    from rrls.report.plots import plot_heatmaps

    # every cell as wide as its neighbours, centred on its point (no half-width edge cells)
    np.testing.assert_allclose(cell_edges(np.array([0.1, 3.0])), [-1.35, 1.55, 4.45])
    assert cell_edges(np.array([1.0, 2.0, 3.0])).tolist() == [0.5, 1.5, 2.5, 3.5]
    pytest.importorskip("matplotlib")
    rows = []
    for algo in ("td3", "m2td3"):
        for point, (pole, cart) in enumerate([(1, 1), (1, 11), (31, 1), (31, 11)]):
            rows.append(
                dict(algorithm=algo, task="invertedpendulum", seed=0, point=point, episode=0)
                | {"polemass": float(pole), "cartmass": float(cart), "return": float(point)}
            )
    ev = pd.DataFrame(rows)
    seen, save = {}, plots.save

    def keep(fig, path):
        seen["fig"] = fig
        return save(fig, path)

    plots.save = keep
    try:
        path = plot_heatmaps(ev, "invertedpendulum", tmp_path / "heat.png", "2d")
    finally:
        plots.save = save
    assert path.stat().st_size > 5_000 and path.with_suffix(".pdf").exists()
    fig = seen["fig"]
    assert fig._suptitle.get_text().startswith("InvertedPendulum: ")
    for ax in fig.axes[:2]:  # the worst point's marker inside the axes, the set outlined
        ((x, y),) = ax.collections[-1].get_offsets()
        assert ax.get_xlim()[0] < x < ax.get_xlim()[1] and ax.get_ylim()[0] < y < ax.get_ylim()[1]
        assert ax.patches, "the set's bounds are outlined"
    assert (
        plot_heatmaps(ev.drop(columns="cartmass"), "invertedpendulum", tmp_path / "x.png", "1d")
        is None
    )


def test_tex_bolds_the_best_of_every_row_shown_escapes_names_and_renames_rows(tmp_path):
    # a submitted-looking name with LaTeX specials, and a reference row above every own row
    returns = {**RETURNS, "my_sac": [[1.0, 2.0, 3.0], [1.5, 2.5, 3.5], [1.2, 2.2, 3.2]]}
    rows = [
        {**r, "values": [v + 100 for v in r["values"]], "mean": r["mean"] + 100}
        if r["algorithm"] == "td3" and r["metric"] == "worst_case"
        else r
        for r in REFERENCE_ROWS
    ]
    ref = Reference(label="lab A", physics="rrls-v5", mesh=3, episodes=2, rows=rows)
    root = _store(tmp_path, returns)
    summary = summarise(root, ref)
    summary["labels"] = {"m2td3@lab A": "M2TD3, lab A's runs", "dr": "DR_uniform"}
    write_tables(summary, root / "tables", paper_results())
    tex = (root / "tables" / "raw_worst_case.tex").read_text()
    # the best of the column is the reference's TD3 (106): bold there, nowhere else
    assert "TD3 (ref. lab A) & $\\mathbf{106.00}" in tex and tex.count("\\mathbf") == 1
    assert "Bold: in each column the highest mean and every row whose 95\\% confidence" in tex
    assert "my\\_sac &" in tex and "my_sac" not in tex.replace("my\\_sac", "")
    assert "M2TD3, lab A's runs &" in tex and "DR\\_uniform &" in tex
    # compiled in a paper's float: tests/test_tex_compiles.py


def test_report_rename_is_name_equals_text(tmp_path, capsys):
    from rrls.cli import main

    root = _store(tmp_path / "bench")
    assert main(["report", str(root), "--no-plots", "--rename", "td3"]) == 2
    assert "--rename 'td3': write NAME=TEXT" in capsys.readouterr().err


def test_every_figure_draws_the_references_rows_beside_the_benchmarks(tmp_path, monkeypatch):
    from rrls.benchmark.store import load_store
    from rrls.report import figures, plots

    drawn: dict[str, set[str]] = {}

    def record(fig, path):
        texts = set()
        for ax in fig.axes:
            legend = ax.get_legend()
            if legend is not None:
                texts |= {t.get_text() for t in legend.get_texts()}
            texts |= {t.get_text() for t in ax.get_yticklabels()}
        drawn[path.name] = texts
        return path

    monkeypatch.setattr(figures, "save", record)
    monkeypatch.setattr(plots, "save", record)
    root = _store(tmp_path)
    summary = summarise(root, _reference())
    summary["labels"] = {"rarl": "RARL, renamed"}
    plots.make_figures(load_store(root), summary, tmp_path / "figures", _reference())
    refs = {"TD3 (ref. lab-a)", "M2TD3 (ref. lab-a)"}
    assert refs <= drawn["performance_profiles.png"]
    assert refs <= drawn["iqm.png"]
    assert {f"{r}: average over the set" for r in refs} <= drawn["returns_invertedpendulum.png"]
    assert "RARL, renamed†" in drawn["returns_invertedpendulum.png"]  # one seed
    # the first algorithm outside the table gets a dark colour, not yellow
    from rrls.report.figstyle import LIGHT, colours

    assert colours(["td3", "my-sac"])["my-sac"] not in LIGHT


def test_a_figure_saved_twice_is_the_same_bytes(tmp_path, monkeypatch):
    # the PDF carries no creation date: a regenerated report leaves committed figures alone
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from rrls.report.figstyle import save

    fig, ax = plt.subplots()
    ax.plot([0, 1], [1, 0])
    monkeypatch.setenv("SOURCE_DATE_EPOCH", "1000000000")  # two saves at two dates
    first = save(fig, tmp_path / "a" / "f.png")
    monkeypatch.setenv("SOURCE_DATE_EPOCH", "1700000000")
    second = save(fig, tmp_path / "b" / "f.png")
    plt.close(fig)
    for suffix in (".png", ".pdf"):
        a, b = first.with_suffix(suffix), second.with_suffix(suffix)
        assert a.read_bytes() == b.read_bytes(), suffix
