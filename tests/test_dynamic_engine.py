"""Dynamic evaluation runs on the static evaluation's engine (two-player lanes): the shipped
``dynamic.csv`` rows are reproduced bit for bit, whatever the workers and batch size; it resumes
from ``out_dir``, has the ``terminated``/``diverged`` columns, handles divergence as static
evaluation does, and takes a ``Protocol``."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from conftest import e2e_after_first

from rrls.evaluation import Protocol, evaluate_dynamic, evaluate_run_dynamic
from rrls.evaluation.lanes import PolicyError
from rrls.uncertainty import UncertaintySet

RESULTS = Path(__file__).resolve().parent.parent / "docs" / "results"
SHIPPED = sorted(RESULTS.glob("*/runs/*/dynamic.csv"))
COLUMNS = ["episode", "seed", "return", "length", "terminated", "diverged"]


def test_every_shipped_run_with_an_adversary_is_checked():
    runs = {p.parent for p in RESULTS.glob("*/runs/*/adversary.npz")}
    assert SHIPPED and {p.parent for p in SHIPPED} == runs


@pytest.mark.parametrize(
    "path", e2e_after_first(SHIPPED), ids=lambda p: f"{p.parts[-4]}/{p.parent.name}"
)
def test_shipped_dynamic_rows_are_reproduced_bit_for_bit(path):
    shipped = pd.read_csv(path)
    kw = {"workers": 2, "batch_size": 3} if "hopper" in path.parent.name else {}
    got = evaluate_run_dynamic(path.parent, episodes=len(shipped), seed=0, **kw).episodes
    assert list(got.columns) == COLUMNS
    for column in shipped.columns:  # the shipped files predate terminated/diverged
        assert np.array_equal(got[column].to_numpy(), shipped[column].to_numpy()), column
    assert not got["diverged"].any()


def still(width: int):
    return lambda obs: np.zeros((len(obs), width))


def push(width: int):
    return lambda obs: np.ones((len(obs), width))


def test_rows_do_not_depend_on_workers_or_batch_size():
    runs = [
        evaluate_dynamic(still(3), push(2), "hopper", uncertainty="2d", episodes=7, **kw).episodes
        for kw in ({"workers": 1, "batch_size": 64}, {"workers": 2, "batch_size": 2})
    ]
    pd.testing.assert_frame_equal(runs[0], runs[1])
    assert runs[0]["terminated"].all()  # a hopper pushed nowhere falls


def test_resume_loads_finished_episodes_and_refuses_other_players(tmp_path):
    calls = []

    def counted(obs):
        calls.append(len(obs))
        return np.zeros((len(obs), 3))

    first = evaluate_dynamic(counted, push(3), "hopper", episodes=4, out_dir=tmp_path)
    stepped = len(calls)
    calls.clear()
    again = evaluate_dynamic(counted, push(3), "hopper", episodes=4, out_dir=tmp_path)
    pd.testing.assert_frame_equal(first.episodes, again.episodes)
    assert stepped > 10 and calls == [8]  # the resume only fingerprints the protagonist
    written = pd.read_csv(tmp_path / "dynamic.csv")
    assert written["return"].tolist() == first.episodes["return"].tolist()
    with pytest.raises(ValueError, match="adversary_fingerprint"):
        evaluate_dynamic(counted, still(3), "hopper", episodes=4, out_dir=tmp_path)


def test_a_diverging_episode_is_flagged_not_raised():
    huge = UncertaintySet(("torsoforce_x",), [0.0], [1e12], [0.0], "hopper/huge-force")
    with pytest.warns(UserWarning, match="diverged"):
        result = evaluate_dynamic(still(3), push(1), "hopper", uncertainty=huge, episodes=2)
    frame = result.episodes
    assert frame["diverged"].all() and np.isfinite(frame["return"]).all()
    assert (frame["length"] < 1000).all()


@pytest.mark.parametrize("who", ["protagonist", "adversary"])
def test_a_bad_action_names_the_player_the_episode_and_the_step(who):
    bad = lambda obs: np.zeros((len(obs), 5))  # noqa: E731
    players = (bad, still(3)) if who == "protagonist" else (still(3), bad)
    with pytest.raises(
        PolicyError, match=rf"^the {who} returned .* episode 0 \(seed \d+\), step 0"
    ):
        evaluate_dynamic(*players, "hopper", episodes=1)


def test_a_protocol_gives_the_same_rows_as_its_keywords():
    keywords = evaluate_dynamic(still(3), push(2), "hopper", uncertainty="2d", episodes=3, seed=4)
    protocol = Protocol("2d", seed=4, dynamic_episodes=3)
    given = evaluate_dynamic(still(3), push(2), "hopper", protocol=protocol)
    pd.testing.assert_frame_equal(keywords.episodes, given.episodes)
    assert keywords.env_id == given.env_id


def test_a_protocol_and_its_keywords_together_are_refused():
    with pytest.raises(ValueError, match="protocol= and episodes, seed"):
        evaluate_dynamic(still(3), push(3), "hopper", protocol=Protocol(), episodes=3, seed=1)


def test_the_protocols_rate_limit_is_the_parameter_games_only():
    protocol = Protocol("2d", dynamic_episodes=1, rate_limit=0.01)
    nr = evaluate_dynamic(still(3), still(3), "hopper", game="nr", protocol=protocol)
    assert nr.env_id == "rrls/probabilistic-action-robust-hopper-v0"
    with pytest.raises(ValueError, match="apply to the parameter game"):
        evaluate_dynamic(still(3), still(3), "hopper", game="nr", rate_limit=0.01, episodes=1)


def test_the_cli_takes_workers_and_an_output_directory(tmp_path, capsys):
    from rrls.cli import main

    run = SHIPPED[-1].parent
    assert main(["evaluate-dynamic", str(run), "--workers", "2", "--out", str(tmp_path)]) == 0
    written = pd.read_csv(tmp_path / "dynamic.csv")
    assert written["return"].tolist() == pd.read_csv(run / "dynamic.csv")["return"].tolist()
    assert "over 10 episodes" in capsys.readouterr().out
