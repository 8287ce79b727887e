"""Dynamic evaluation checks its arguments as static evaluation does (one line naming the
argument), and a policy's non-finite action is reported naming which player, in every game."""

from __future__ import annotations

import math

import numpy as np
import pytest

from rrls.evaluation.dynamic import evaluate_dynamic
from rrls.evaluation.lanes import PolicyError

BAD = [
    ("episodes", 2.5),
    ("episodes", 0),
    ("episodes", True),
    ("episodes", "3"),
    ("batch_size", 0),
    ("batch_size", -3),
    ("batch_size", 2.5),
    ("history", 0),
    ("seed", -1),
    ("seed", 2**32),
    ("seed", 1.5),
    ("alpha", math.nan),
    ("alpha", -0.1),
    ("alpha", 1.5),
    ("rate_limit", math.nan),
    ("rate_limit", math.inf),
    ("rate_limit", -1.0),
    ("rate_limit", 0.0),
]


def zeros(width: int):
    return lambda obs: np.zeros((len(obs), width))


def nans(width: int):
    return lambda obs: np.full((len(obs), width), np.nan)


@pytest.mark.parametrize(("name", "value"), BAD)
def test_a_bad_argument_is_named_with_its_value(name, value):
    with pytest.raises(ValueError, match=rf"^{name} must be ") as err:
        evaluate_dynamic(zeros(1), zeros(1), "invertedpendulum", uncertainty="1d", **{name: value})
    assert str(err.value).endswith(f"got {value!r}")


@pytest.mark.parametrize(
    "game",
    [
        {"game": "adversarial", "uncertainty": "1d"},  # the plain parameter game
        {"game": "adversarial", "uncertainty": "1d", "rate_limit": 0.1},  # TC-RMDP
        {"game": "adversarial", "uncertainty": "rarl"},  # forces
        {"game": "nr"},
        {"game": "pr"},
    ],
)
@pytest.mark.parametrize("who", ["protagonist", "adversary"])
def test_a_non_finite_action_names_the_player(game, who):
    width = {"nr": 1, "pr": 1}.get(game["game"], 2 if game.get("uncertainty") == "rarl" else 1)
    protagonist = nans(1) if who == "protagonist" else zeros(1)
    adversary = nans(width) if who == "adversary" else zeros(width)
    with pytest.raises(PolicyError, match=f"the {who} returned non-finite actions"):
        evaluate_dynamic(protagonist, adversary, "invertedpendulum", episodes=1, **game)
