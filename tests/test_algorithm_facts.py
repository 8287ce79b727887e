"""Two algorithm facts the table declares and the rest of rrls reads: the anchors of the paper's
normalised score (0 = TD3's mean, 1 = M2TD3's, Tables 4-5) and the ``Config`` fields the
benchmark's ``--learning-rate`` sets (TD3's one rate; SAC's two are its own)."""

from __future__ import annotations

from dataclasses import replace

import pytest

from rrls.algorithms import (
    ALGORITHMS,
    ANCHORS,
    AlgorithmInfo,
    normalisers,
    paper_five,
    register_algorithm,
)
from rrls.benchmark.grid import make_spec
from rrls.benchmark.presets import ALGOS


def test_the_table_declares_one_row_per_anchor_of_the_normalised_score():
    anchors = {a: [n for n, row in ALGORITHMS.items() if row.anchor == a] for a in ANCHORS}
    assert anchors == {0.0: ["td3"], 1.0: ["m2td3"]}  # the paper's Tables 4-5
    assert normalisers() == ("td3", "m2td3")


def test_a_plugin_cannot_add_a_third_anchor():
    with pytest.raises(TypeError, match="anchor"):
        AlgorithmInfo("third", "Third", "mypkg.third:Learner", anchor=0.0)  # type: ignore[call-arg]
    # a built-in's row copied under another name (benchmarks/authors_variants.py) does not anchor
    copy = replace(ALGORITHMS["m2td3"], name="m2td3-copy", display="M2TD3 (copy)")
    register_algorithm(copy)
    try:
        assert copy.anchor is None and normalisers() == ("td3", "m2td3")
    finally:
        del ALGORITHMS["m2td3-copy"]


def test_rate_fields_are_config_field_names():
    bare: object = "learning_rate"  # a string, not a tuple of one
    with pytest.raises(ValueError, match="rate_fields"):
        AlgorithmInfo("x", "X", "mypkg.x:Learner", rate_fields=bare)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="rate_fields"):
        AlgorithmInfo("x", "X", "mypkg.x:Learner", rate_fields=("learning rate",))


def test_the_learning_rate_reaches_the_fields_each_row_names():
    spec = make_spec("quick")
    assert spec.learning_rate == 1e-3
    for name, row in ALGORITHMS.items():
        hyper = spec.hyperparameters(name)
        assert {f: hyper[f] for f in row.rate_fields} == dict.fromkeys(row.rate_fields, 1e-3)
    # the rule it replaces: the paper's five (presets.ALGOS) take TD3's one rate, no other does
    assert paper_five() == ALGOS
    takes = {n for n in ALGORITHMS if "learning_rate" in spec.hyperparameters(n)}
    assert takes == set(ALGOS)
    assert ALGORITHMS["sac"].rate_fields == ALGORITHMS["sacdr"].rate_fields == ()
    # a name no row declares (an entry point, package.module:Learner) gets none
    assert "learning_rate" not in spec.hyperparameters("mypkg.x:Learner")
    # no --learning-rate: the rows' own defaults
    assert "learning_rate" not in make_spec("paper").hyperparameters("td3")


def test_a_plugin_row_names_its_own_rates():
    register_algorithm(
        AlgorithmInfo("tworates", "TwoRates", "mypkg.two:Learner", rate_fields=("lr_a", "lr_b"))
    )
    register_algorithm(AlgorithmInfo("norate", "NoRate", "mypkg.none:Learner"))
    try:
        spec = make_spec("quick")
        hyper = spec.hyperparameters("tworates")
        assert hyper["lr_a"] == hyper["lr_b"] == 1e-3 and "learning_rate" not in hyper
        assert not {"learning_rate", "lr_a", "lr_b"} & set(spec.hyperparameters("norate"))
    finally:
        del ALGORITHMS["tworates"], ALGORITHMS["norate"]
