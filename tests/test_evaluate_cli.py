"""``rrls evaluate`` and ``rrls plot`` from the command line: an evaluation resumes from its
saved chunks to the same numbers, a policy without a task is refused, and the plots of 1D and 3D
sets are drawn on one colour scale and name the policy."""

from __future__ import annotations

import json

import pandas as pd
import pytest
from conftest import random_policy

from rrls.evaluation import EvaluationResult, evaluate


def test_cli_evaluate_resume_and_plot(tmp_path, capsys):
    from rrls.cli import main

    policy = random_policy("invertedpendulum")
    policy.metadata = {"task": "invertedpendulum"}
    path = policy.save(tmp_path / "policy.npz")
    out = tmp_path / "eval"
    args = [
        "evaluate",
        str(path),
        "--uncertainty",
        "2d",
        "--mesh",
        "3",
        "--episodes",
        "2",
        "--workers",
        "1",
        "--out",
        str(out),
    ]
    assert main(args) == 0
    printed = capsys.readouterr().out
    summary = json.loads((out / "summary.json").read_text())
    assert f"{summary['worst_case']:,.2f}" in printed and "average case" in printed
    assert (
        summary["mesh"] == 3 and summary["episodes"] == 2 and summary["task"] == "invertedpendulum"
    )
    episodes = pd.read_parquet(out / "episodes.parquet")
    assert len(episodes) == 18
    # same command again: everything is loaded from the saved chunks, same numbers
    assert main(args) == 0
    assert json.loads((out / "summary.json").read_text())["worst_case"] == summary["worst_case"]
    assert main(["plot", str(out)]) == 0
    png = (out / "returns.png").read_bytes()
    assert png[:8] == b"\x89PNG\r\n\x1a\n" and len(png) > 10_000


@pytest.mark.parametrize("uncertainty", ["1d", "3d"])
def test_plots_for_1d_and_3d(tmp_path, uncertainty):
    from rrls.evaluation import plot_result

    result = evaluate(
        random_policy("hopper"),
        "hopper",
        uncertainty,
        mesh=3,
        episodes=1,
        workers=1,
        out_dir=tmp_path,
    )
    path = plot_result(tmp_path)
    assert path.exists() and path.stat().st_size > 10_000
    with pytest.raises(ValueError, match="give a path"):
        plot_result(result)


def test_cli_evaluate_needs_a_task(tmp_path, capsys):
    from rrls.cli import main

    path = random_policy("hopper").save(tmp_path / "p.npz")
    assert main(["evaluate", str(path)]) == 2
    assert capsys.readouterr().err.strip() == (
        "rrls evaluate: error: --task is required (the policy does not record its task)"
    )


def test_3d_plot_shares_one_colour_scale_and_names_the_policy(tmp_path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from rrls.evaluation import plot_result

    policy = random_policy("hopper")
    policy.metadata.update(algorithm="m2td3", seed=7)
    out = tmp_path / "ev"
    evaluate(policy, "hopper", "3d", mesh=2, episodes=1, out_dir=out, max_episode_steps=15)
    seen = {}
    real_savefig = plt.Figure.savefig

    def capture(fig, *args, **kwargs):
        seen["fig"] = fig
        return real_savefig(fig, *args, **kwargs)

    plt.Figure.savefig = capture
    try:
        plot_result(out)
    finally:
        plt.Figure.savefig = real_savefig
    fig = seen["fig"]
    assert fig._suptitle.get_text().startswith("m2td3 seed 7 on hopper / 3d")
    meshes = [a.collections[0] for a in fig.axes if a.get_label() != "<colorbar>"][:3]
    assert len(meshes) == 3
    assert len({m.get_clim() for m in meshes}) == 1  # one scale for the three slices
    table = EvaluationResult.load(out).per_point["mean_return"]
    assert meshes[0].get_clim() == (table.min(), table.max())
