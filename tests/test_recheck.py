"""The rechecked worst case: the lowest mesh points re-evaluated with fresh, independent episode
seeds, and a low quantile of the point means, beside the paper's minimum (which it never
changes: the protocol's fingerprint leaves it out)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from rrls.benchmark.grid import make_spec
from rrls.evaluation import BatchInvariant, Protocol, evaluate
from rrls.evaluation.lanes import episode_seeds
from rrls.evaluation.recheck import Recheck, recheck, recheck_seeds

PROTOCOL = Protocol("1d", mesh=6, episodes=2, seed=3)


def wobbly() -> BatchInvariant:
    """A pendulum controller good enough to balance sometimes (returns differ by episode)."""
    k = np.array([1.0, 4.0, 0.3, 0.9])
    return BatchInvariant(lambda obs: np.clip((obs @ k)[:, None], -3.0, 3.0))


def test_fresh_seeds_share_nothing_with_the_meshs():
    # 32-bit seeds from distinct streams: over 1 000 points a value or two may repeat by chance
    # (2 % odds); over 100 points none does
    mesh = episode_seeds(0, 100, 5)
    fresh = recheck_seeds(0, np.arange(100), 20)
    assert not set(mesh.ravel().tolist()) & set(fresh.ravel().tolist())
    # a point's fresh seeds depend on the point, not on which others are rechecked
    assert (recheck_seeds(0, np.array([7, 3]), 4)[1] == recheck_seeds(0, np.array([3]), 4)).all()


def test_the_lowest_points_are_rechecked_and_the_quantile_is_the_meshs():
    result = evaluate(wobbly(), "invertedpendulum", protocol=PROTOCOL, workers=1)
    out = recheck(wobbly(), "invertedpendulum", PROTOCOL, result.episodes, Recheck(2, 3, 0.25))
    means = result.per_point["mean_return"].to_numpy()
    assert out["recheck"]["points"] == np.argsort(means, kind="stable")[:2].tolist()
    assert out["recheck"]["mesh_means"] == pytest.approx(np.sort(means)[:2].tolist())
    assert out["worst_case_q"] == pytest.approx(np.quantile(means, 0.25))
    assert out["worst_case_rechecked"] == min(out["recheck"]["fresh_means"])
    again = recheck(
        wobbly(), "invertedpendulum", PROTOCOL, result.episodes, Recheck(2, 3, 0.25), workers=2
    )
    assert again == out  # the same numbers whatever the worker count


def test_the_fresh_means_are_the_plain_evaluation_at_those_points_and_seeds():
    """Each fresh mean is what the engine gives for that point with those seeds: a one-point
    evaluation of the same policy there, row for row."""
    from dataclasses import replace

    from rrls.evaluation import engine
    from rrls.evaluation.lanes import Rollouts

    result = evaluate(wobbly(), "invertedpendulum", protocol=PROTOCOL, workers=1)
    out = recheck(wobbly(), "invertedpendulum", PROTOCOL, result.episodes, Recheck(1, 4))
    (p,) = out["recheck"]["points"]
    spec = Rollouts.from_plan(PROTOCOL.plan("invertedpendulum"), PROTOCOL)
    one = replace(spec, points=spec.points[[p]], seeds=recheck_seeds(3, np.array([p]), 4))
    cols = engine.run(one, wobbly(), workers=1, progress=False)
    assert out["recheck"]["fresh_means"] == [pytest.approx(cols["return"].mean())]


def test_recheck_leaves_the_fingerprints_and_old_files_as_they_were():
    with_recheck = PROTOCOL.replace(recheck=Recheck())
    assert with_recheck.fingerprint() == PROTOCOL.fingerprint()
    assert "recheck" not in PROTOCOL.to_json()
    assert Protocol.from_json(with_recheck.to_json()) == with_recheck
    spec = make_spec("smoke", recheck={"worst": 2, "episodes": 3, "quantile": 0.1})
    assert spec.fingerprints() == make_spec("smoke").fingerprints()
    assert "recheck" not in make_spec("smoke").to_json()


@pytest.mark.parametrize(
    "bad", [{"worst": 0}, {"episodes": True}, {"quantile": 2}, {"k": 1}, "10x20"]
)
def test_bad_recheck_settings_are_one_line(bad):
    with pytest.raises(ValueError, match="recheck") as err:
        Protocol("1d", recheck=bad)
    assert "\n" not in str(err.value)


def test_a_benchmark_with_recheck_records_and_reports_it(tmp_path):
    from rrls.benchmark.store import build_store
    from rrls.report.writer import make_report
    from rrls.submissions import submit
    from rrls.submissions.steps import create_benchmark

    root = tmp_path / "bench"
    create_benchmark(
        root, "smoke", ("invertedpendulum",), recheck={"worst": 2, "episodes": 3, "quantile": 0.1}
    )
    for seed in (0, 1):
        submit(root, "mine", "invertedpendulum", seed, wobbly(), workers=1, progress=False)
    result = json.loads(
        (root / "runs" / "mine-invertedpendulum-1d-seed0" / "result.json").read_text()
    )
    assert result["recheck"]["episodes"] == 3 and len(result["recheck"]["points"]) == 2
    assert result["worst_case_rechecked"] == min(result["recheck"]["fresh_means"])
    build_store(root)
    make_report(root, plots=False)
    text = (root / "report" / "report.md").read_text()
    assert "## Worst case, rechecked with fresh episodes" in text
    (row,) = [line for line in text.splitlines() if line.startswith("| InvertedPendulum | mine")]
    assert "| 2 of 2 |" in row


@pytest.mark.parametrize(
    ("text", "expected"),
    [("10x20", (10, 20, 0.05)), (" 3 x 5 @ 0.1 ", (3, 5, 0.1)), ("1x1@0", (1, 1, 0.0))],
)
def test_the_benchmark_flag_reads_k_x_e_at_q(text, expected):
    from rrls.argtypes import recheck_value

    assert Recheck(**recheck_value(text)) == Recheck(*expected)


@pytest.mark.parametrize("text", ["10", "0x5", "2y3", "3x4@2"])
def test_the_benchmark_flag_refuses_other_text_in_one_line(text, capsys):
    from rrls.cli import main

    code = main(["benchmark", "--out", "b", "--preset", "smoke", "--recheck", text])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and "--recheck" in err[0]
