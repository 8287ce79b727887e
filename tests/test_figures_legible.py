"""The report's figures read without their caption: no legend over data, a unit on every axis,
the reference's rows told apart from the benchmark's own by colour and line style, † on every
label of a method from fewer than 3 seeds, titles optional.

The benchmark is the smoke protocol on a 5-point mesh, its runs written directly: fixed linear
controllers as TD3 and M2TD3 (3 seeds each, with training curves), a policy submitted from 2
seeds, and a reference exported from a second such benchmark: seconds, no training.
"""

from __future__ import annotations

import re
from dataclasses import replace
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from rrls.benchmark.grid import RunKey, make_spec
from rrls.benchmark.store import build_store, write_result
from rrls.evaluation import BatchInvariant, evaluate
from rrls.files import atomic_write_json, write_checked_table
from rrls.report.exported import export_reference
from rrls.rundir import SCALARS
from rrls.submissions import submit

#: the long end-to-end tier (.ci/run runs it after the default suite)
pytestmark = pytest.mark.e2e

pytest.importorskip("scipy")
pytest.importorskip("matplotlib")

TASK = "invertedpendulum"


def linear(*gains: float) -> BatchInvariant:
    """A linear controller of InvertedPendulum (batch-invariant: exact episodes)."""
    k = np.asarray(gains, dtype=float)
    return BatchInvariant(lambda obs: np.clip((obs @ k)[:, None], -3.0, 3.0))


#: per baseline, a controller per seed (different gains: the seeds differ)
BASELINES = {
    "td3": [linear(1.0, 1.0 + s, 0.0, 0.2) for s in range(3)],
    "m2td3": [linear(0.0, 5.0 + s, 0.0, 1.0) for s in range(3)],
}


def write_runs(root: Path, gain: float = 1.0, mesh: int = 5) -> Path:
    """A smoke-protocol benchmark on a ``mesh``-point set whose TD3 and M2TD3 runs are fixed
    controllers (``gain`` scales them: another lab's runs), each with a training curve."""
    spec = replace(make_spec("smoke"), algos=tuple(BASELINES), seeds=(0, 1, 2), mesh=mesh)
    atomic_write_json(root / "benchmark.json", spec.to_json())
    for algo, policies in BASELINES.items():
        for seed, policy in enumerate(policies):
            run = root / "runs" / RunKey(algo, TASK, seed).name(spec.uncertainty)
            scaled = BatchInvariant(lambda obs, p=policy: p(obs * gain))
            res = evaluate(
                scaled, TASK, "1d", spec.mesh, spec.episodes, spec.eval_seed, 1,
                out_dir=run / "eval",
            )  # fmt: skip
            steps = np.arange(10, spec.steps + 1, 10)
            rise = 1.0 - np.exp(-steps / (60.0 + 40 * seed))
            write_checked_table(
                run / SCALARS,
                pd.DataFrame(
                    {
                        "step": steps,
                        "metric": "charts/episode_return",
                        "value": res.average_case * rise,
                    }
                ),
            )
            result = {"algorithm": algo, "task": TASK, "uncertainty": "1d", "seed": seed}
            write_result(
                run,
                result
                | {
                    "steps": spec.steps,
                    "worst_case": res.worst_case,
                    "average_case": res.average_case,
                    "versions": res.config["versions"],
                },
            )
    return root


def make_bench(tmp: Path) -> tuple[Path, Path]:
    """The benchmark (with a 2-seed submission) and a reference file from another one."""
    other = write_runs(tmp / "other", gain=0.7)
    build_store(other)
    from rrls.report.writer import make_report

    make_report(other, plots=False)
    ref = export_reference(other, tmp / "quick.json", label="quick").path
    root = write_runs(tmp / "bench")
    for seed in (0, 1):
        submit(root, "mine", TASK, seed, linear(0.0, 8.0 + seed, 0.0, 0.6), workers=1)
    build_store(root)
    return root, Path(ref)


# --- what a figure is checked for ------------------------------------------------------------
def data_paths(ax) -> list:
    """Every line and band of ``ax`` in display coordinates: ``[(path, filled)]``."""
    paths = [(line.get_transform().transform_path(line.get_path()), False) for line in ax.lines]
    for coll in ax.collections:
        transform = coll.get_transform()
        paths += [(transform.transform_path(p), True) for p in coll.get_paths()]
    return paths


def legends(fig) -> list:
    return [*(ax.get_legend() for ax in fig.axes if ax.get_legend()), *fig.legends]


def covered(fig) -> list[str]:
    """What a legend of ``fig`` lies on: the axes it overlaps whose lines or bands cross it."""
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    hits = []
    for legend in legends(fig):
        box = legend.get_window_extent(renderer)
        for ax in fig.axes:
            if not ax.get_visible() or not box.overlaps(ax.get_window_extent(renderer)):
                continue  # outside these axes: over none of their data
            crossed = [p for p, filled in data_paths(ax) if p.intersects_bbox(box, filled=filled)]
            if crossed:
                hits.append(f"legend over {len(crossed)} artists of axes {ax.get_label()!r}")
    return hits


def numeric(labels) -> bool:
    try:
        [float(t.get_text().replace("\N{MINUS SIGN}", "-")) for t in labels]
    except ValueError:
        return False
    return bool(labels)


UNIT = re.compile(r"\[[^\]]+\]$")


def unitless_axes(fig) -> list[str]:
    """Every axis showing numbers whose label states no unit ``[...]``."""
    fig.canvas.draw()
    missing = []
    for ax in fig.axes:
        if not ax.get_visible():
            continue
        for axis in (ax.xaxis, ax.yaxis):
            shown = [t for t in axis.get_ticklabels() if t.get_visible() and t.get_text()]
            if numeric(shown) and not UNIT.search(axis.get_label_text()):
                missing.append(f"{axis.__name__} of {ax.get_label()!r}: {axis.get_label_text()!r}")
    return missing


def texts(fig) -> list[str]:
    """Every label a reader reads a row by: legend entries, tick labels, panel titles."""
    fig.canvas.draw()
    out = [t.get_text() for legend in legends(fig) for t in legend.get_texts()]
    for ax in fig.axes:
        out += [t.get_text() for t in ax.get_yticklabels()] + [ax.get_title()]
    return [t for t in out if t]


def styles(fig, gid: str) -> tuple[set[str], set[str]]:
    """The colours and the line styles (of lines with one) of the artists of row ``gid``."""
    from matplotlib.colors import to_hex

    colours, lines = set(), set()
    for ax in fig.axes:
        for line in ax.lines:
            if line.get_gid() == gid:
                colours.add(to_hex(line.get_color()))
                if line.get_linestyle() not in ("None", "none", ""):
                    lines.add(line.get_linestyle())
    return colours, lines


def test_the_checks_catch_a_legend_over_a_line_and_an_axis_without_unit():
    # what returns_<task>.png was: a frameless legend inside the axes, crossed by a dashed
    # reference line, and axes named without units
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots()
    ax.plot([0, 1], [0, 1], label="TD3")
    ax.axhline(0.5, ls="--", label="TD3 (ref. quick): average over the set")
    ax.legend(loc="center", frameon=False)
    ax.set_xlabel("polemass")
    ax.set_ylabel("mean return")
    assert len(covered(fig)) == 1 and len(unitless_axes(fig)) == 2
    plt.close(fig)


# --- the report ------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def drawn(tmp_path_factory):
    """The report of the benchmark and every figure of it (open), with and without titles."""
    from rrls.benchmark.store import load_store
    from rrls.report.plots import make_figures
    from rrls.report.reference import load_reference
    from rrls.report.writer import make_report

    tmp = tmp_path_factory.mktemp("figures")
    root, ref = make_bench(tmp)
    make_report(root, reference=ref, labels={"mine": "mine (submitted)"})
    summary = __import__("json").loads((root / "report" / "summary.json").read_text())
    figs, bare = {}, {}
    made = make_figures(load_store(root), summary, tmp / "out", load_reference(ref), keep=figs)
    make_figures(load_store(root), summary, tmp / "bare", load_reference(ref), False, bare)
    yield {"root": root, "ref": ref, "figs": figs, "bare": bare, "made": made, "tmp": tmp}
    import matplotlib.pyplot as plt

    for fig in [*figs.values(), *bare.values()]:
        plt.close(fig)


EXPECTED = {
    "curves_episode_return.png",
    "returns_invertedpendulum.png",
    "performance_profiles.png",
    "iqm.png",
    "probability_of_improvement.png",
}


def test_every_figure_is_kept_and_written(drawn):
    assert set(drawn["figs"]) == EXPECTED == {p.name for _, p in drawn["made"]}
    written = {p.name for p in (drawn["root"] / "report" / "figures").glob("*.png")}
    assert written == EXPECTED


def test_no_legend_lies_over_data(drawn):
    for name, fig in drawn["figs"].items():
        assert covered(fig) == [], name
    with_legend = {n for n, f in drawn["figs"].items() if legends(f)}
    assert {"returns_invertedpendulum.png", "performance_profiles.png"} <= with_legend
    for name in with_legend:  # framed, beside the axes
        for legend in legends(drawn["figs"][name]):
            assert legend.get_frame_on(), name


def test_every_axis_with_numbers_states_its_unit(drawn):
    for name, fig in drawn["figs"].items():
        assert unitless_axes(fig) == [], name
    returns = drawn["figs"]["returns_invertedpendulum.png"].axes[0]
    assert returns.get_xlabel() == "polemass [kg]"  # from the task's table: a body mass
    assert returns.get_ylabel().endswith("[sum of rewards]")
    curves = drawn["figs"]["curves_episode_return.png"].axes[0]
    assert curves.get_xlabel().endswith("[environment steps]")
    profile = drawn["figs"]["performance_profiles.png"].axes[0]
    assert profile.get_xlabel().endswith("[0 = TD3, 1 = M2TD3]")


def test_a_parameters_unit_comes_from_its_field():
    from rrls.report.figstyle import param_unit

    assert param_unit("hopper", "torsomass") == "kg"
    assert param_unit("hopper", "worldfriction") == "unitless"  # a friction coefficient
    assert param_unit("hopper", "torsoforce_x") == "N"
    assert param_unit("hopper", "nothing") == param_unit("no-such-task", "x") == "unit not known"


@pytest.mark.parametrize(
    "name", ["returns_invertedpendulum.png", "performance_profiles.png", "iqm.png"]
)
@pytest.mark.parametrize("algo", ["td3", "m2td3"])
def test_reference_rows_differ_in_colour_and_line_style(drawn, name, algo):
    fig = drawn["figs"][name]
    own, theirs = styles(fig, f"results:{algo}"), styles(fig, f"reference_results:{algo}")
    assert own[0] and theirs[0], "both rows drawn"
    assert own[0].isdisjoint(theirs[0]), "a reference's row in another colour"
    assert theirs[1] and own[1].isdisjoint(theirs[1]), "and another line style"


def test_reference_bands_are_hatched_and_light(drawn):
    fig = drawn["figs"]["performance_profiles.png"]
    bands = [c for ax in fig.axes for c in ax.collections if c.get_gid()]
    own = [b for b in bands if b.get_gid().startswith("results:")]
    theirs = [b for b in bands if b.get_gid().startswith("reference_results:")]
    assert own and theirs
    assert all(b.get_alpha() <= 0.15 and not b.get_hatch() for b in own)
    assert all(b.get_hatch() and not b.get_facecolor()[:, 3].any() for b in theirs)


def test_a_few_seed_method_carries_the_dagger_in_every_figure(drawn):
    seen = set()
    for name, fig in drawn["figs"].items():
        for text in texts(fig):
            for part in re.split(r" > |: ", text):  # a pair of P(X > Y); a reference's line
                if part.startswith("mine"):  # submitted from 2 seeds
                    seen.add(name)
                    assert re.fullmatch(r"mine \(submitted\)‡?†( \(2\))?", part), (name, text)
                elif "TD3" in part:  # 3 seeds
                    assert "†" not in part, (name, text)
    # every figure that draws it (a submission has no training curve)
    assert seen == EXPECTED - {"curves_episode_return.png"}


def test_titles_are_optional(drawn):
    titled = drawn["figs"]["returns_invertedpendulum.png"]
    assert "return over the uncertainty set" in titled.get_suptitle()
    for name, fig in drawn["bare"].items():
        assert fig.get_suptitle() == "", name
        panels = [ax for ax in fig.axes if ax.get_visible() and ax.get_label() != "<colorbar>"]
        if len(panels) == 1:  # one task: nothing to tell apart
            assert panels[0].get_title() == "", name


def test_rrls_report_no_titles_reaches_the_figures(drawn, monkeypatch):
    from rrls.cli import main
    from rrls.report import writer as report

    seen = {}
    real = report.make_report

    def spy(root, **kw):
        seen.update(kw)
        return real(root, **{**kw, "plots": False})

    monkeypatch.setattr(report, "make_report", spy)
    assert (
        main(["report", str(drawn["root"]), "--no-titles", "--reference", str(drawn["ref"])]) == 0
    )
    assert seen["titles"] is False


def test_a_submissions_only_report_draws_the_probability_of_improvement(drawn):
    from rrls.benchmark.store import load_store
    from rrls.report.plots import make_figures
    from rrls.report.reference import load_reference
    from rrls.report.writer import make_report
    from rrls.submissions.steps import create_benchmark

    root = drawn["tmp"] / "submissions"
    create_benchmark(root, "smoke", (TASK,), mesh=5)
    for seed in (0, 1):
        submit(root, "mine", TASK, seed, linear(0.0, 8.0 + seed, 0.0, 0.6), workers=1)
    build_store(root)
    make_report(root, reference=drawn["ref"])
    md = (root / "report" / "report.md").read_text()
    assert "## Probability of improvement over TD3" in md  # the table
    assert "(figures/probability_of_improvement.png)" in md  # and its figure
    summary = __import__("json").loads((root / "report" / "summary.json").read_text())
    figs: dict = {}
    make_figures(load_store(root), summary, root / "check", load_reference(drawn["ref"]), keep=figs)
    fig = figs["probability_of_improvement.png"]
    try:
        ax = fig.axes[0]
        names = [t.get_text() for t in ax.get_yticklabels()]
        assert names == [
            "mine (submitted)‡† > TD3 (ref. quick)",
            "mine (submitted)‡† > M2TD3 (ref. quick)",
        ]
        # against TD3: the table's number
        table = summary["aggregate"]["mine"]["poi_over_td3_worst_case"]["value"]
        td3 = [ln for ln in ax.lines if ln.get_gid() == "results:mine>reference_results:td3"]
        assert td3 and any(np.isclose(ln.get_xdata()[0], table) for ln in td3)
        assert covered(fig) == [] and unitless_axes(fig) == []
    finally:
        import matplotlib.pyplot as plt

        for f in figs.values():
            plt.close(f)


def test_a_2d_set_heatmap_states_units_and_drops_its_title(tmp_path):
    import matplotlib.pyplot as plt

    from rrls.report.plots import plot_heatmaps

    rows = [
        {"task": TASK, "algorithm": algo, "seed": 0, "point": i * 3 + j, "episode": 0}
        | {"polemass": pm, "cartmass": cm, "return": float(k * 100 + pm + cm)}
        for k, algo in enumerate(("td3", "m2td3"))
        for i, pm in enumerate((1.0, 16.0, 31.0))
        for j, cm in enumerate((1.0, 6.0, 11.0))
    ]
    for titles in (True, False):
        figs: dict = {}
        plot_heatmaps(pd.DataFrame(rows), TASK, tmp_path / "h.png", "2d", titles=titles, keep=figs)
        fig = figs["h.png"]
        assert unitless_axes(fig) == []
        assert fig.axes[0].get_xlabel() == "polemass [kg]"
        assert fig.axes[0].get_ylabel() == "cartmass [kg]"
        assert fig.axes[-1].get_ylabel() == "mean return [sum of rewards]"  # the colour bar
        assert [ax.get_title() for ax in fig.axes[:2]] == ["TD3", "M2TD3"]  # the panels' names
        assert bool(fig.get_suptitle()) is titles
        plt.close(fig)
