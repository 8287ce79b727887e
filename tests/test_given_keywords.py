"""Given means given: beside ``protocol=``, a keyword the protocol holds is refused whenever the
caller passed it, its default value included (the protocol's would silently win); without a
protocol, the keywords' defaults are the documented ones."""

from __future__ import annotations

import inspect

import numpy as np
import pandas as pd
import pytest

from rrls.evaluation import (
    MLPPolicy,
    Protocol,
    evaluate,
    evaluate_dynamic,
    search_worst_case,
)
from rrls.evaluation.defaults import Default, or_default

HOPPER = MLPPolicy.random(11, 3, (8,), seed=0)

#: each entry's protocol keywords with their documented defaults
EVALUATE = {
    "uncertainty": "3d",
    "mesh": 10,
    "episodes": 5,
    "seed": 0,
    "endpoint": None,
    "max_episode_steps": None,
    "disruptors": None,
    "schedule": None,
    "context": False,
    "split": None,
    "paper": False,
}
DYNAMIC = {
    "uncertainty": "3d",
    "episodes": 10,
    "seed": 0,
    "rate_limit": None,
    "context": False,
    "paper": False,
    "rate_game": "tc",
}
SEARCH = {"uncertainty": "3d", "episodes": 1, "seed": 0, "max_episode_steps": None}


def _still(width: int):
    return lambda obs: np.zeros((len(obs), width))


@pytest.mark.parametrize(
    ("function", "defaults"),
    [(evaluate, EVALUATE), (evaluate_dynamic, DYNAMIC), (search_worst_case, SEARCH)],
    ids=["evaluate", "evaluate_dynamic", "search_worst_case"],
)
def test_the_signature_shows_each_documented_default_marked_as_not_passed(function, defaults):
    params = inspect.signature(function).parameters
    shown = {name: params[name].default for name in defaults}
    assert all(isinstance(d, Default) for d in shown.values()), shown
    assert {name: or_default(d) for name, d in shown.items()} == defaults
    for name, value in defaults.items():  # help() shows the value; the docstring names it
        assert repr(value) in repr(shown[name])
    assert "Defaults" in function.__doc__ or "defaults" in function.__doc__


@pytest.mark.parametrize(("keyword", "value"), EVALUATE.items())
def test_evaluate_refuses_a_keyword_passed_beside_a_protocol_even_at_its_default(keyword, value):
    protocol = Protocol("1d", mesh=2, episodes=1)
    with pytest.raises(ValueError, match=f"got protocol= and {keyword}: ") as caught:
        evaluate(HOPPER, "hopper", protocol=protocol, **{keyword: value})
    assert "\n" not in str(caught.value) and "protocol.replace(" in str(caught.value)


def test_evaluate_names_every_keyword_passed_beside_a_protocol_positional_ones_too():
    with pytest.raises(ValueError, match=r"got protocol= and uncertainty, mesh, seed: "):
        evaluate(HOPPER, "hopper", Protocol("1d"), 10, seed=0, uncertainty="3d")
    with pytest.raises(TypeError, match="multiple values for argument 'protocol'"):
        evaluate(HOPPER, "hopper", "3d", protocol=Protocol("1d"))  # a set where it goes


def test_the_set_as_third_argument_is_read_as_uncertainty_and_once_only():
    small = {"mesh": 2, "episodes": 1, "max_episode_steps": 5, "workers": 1}
    positional = evaluate(HOPPER, "hopper", "1d", **small)
    keyword = evaluate(HOPPER, "hopper", uncertainty="1d", **small)
    pd.testing.assert_frame_equal(positional.episodes, keyword.episodes)
    with pytest.raises(TypeError, match="the set twice"):
        evaluate(HOPPER, "hopper", "1d", uncertainty="2d", **small)


@pytest.mark.parametrize(("keyword", "value"), DYNAMIC.items())
def test_evaluate_dynamic_refuses_a_keyword_passed_beside_a_protocol_at_its_default(keyword, value):
    players = (_still(3), _still(3))
    with pytest.raises(ValueError, match=f"got protocol= and {keyword}: ") as caught:
        evaluate_dynamic(*players, "hopper", protocol=Protocol(), **{keyword: value})
    field = {"episodes": "dynamic_episodes", "paper": "physics"}.get(keyword, keyword)
    assert f"protocol.replace({field}=...)" in str(caught.value)


@pytest.mark.parametrize(("keyword", "value"), SEARCH.items())
def test_the_search_refuses_a_keyword_passed_beside_a_protocol_at_its_default(keyword, value):
    with pytest.raises(ValueError, match=f"got protocol= and {keyword}: "):
        search_worst_case(HOPPER, "hopper", protocol=Protocol("1d"), **{keyword: value})


def test_evaluate_without_a_protocol_runs_the_documented_defaults():
    small = {"mesh": 2, "max_episode_steps": 5, "workers": 1}
    implicit = evaluate(HOPPER, "hopper", **small)  # the 3d set, 5 episodes, seed 0
    explicit = evaluate(HOPPER, "hopper", "3d", episodes=5, seed=0, paper=False, **small)
    protocol = evaluate(HOPPER, "hopper", protocol=Protocol(mesh=2, max_episode_steps=5))
    assert len(implicit.per_point) == 8 and len(implicit.episodes) == 8 * 5
    pd.testing.assert_frame_equal(implicit.episodes, explicit.episodes)
    pd.testing.assert_frame_equal(implicit.episodes, protocol.episodes)
    assert implicit.config["physics"] == explicit.config["physics"] == "v5"


def test_evaluate_dynamic_without_a_protocol_runs_the_documented_defaults():
    implicit = evaluate_dynamic(_still(3), _still(3), "hopper", batch_size=10)
    explicit = evaluate_dynamic(
        _still(3), _still(3), "hopper", uncertainty="3d", episodes=10, seed=0, batch_size=10
    )
    assert len(implicit.episodes) == 10
    pd.testing.assert_frame_equal(implicit.episodes, explicit.episodes)
    assert implicit.env_id == explicit.env_id
