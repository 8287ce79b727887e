"""Uncertainty sets: geometry, validation, and the paper's tables."""

from __future__ import annotations

import json
import pathlib

import numpy as np
import pytest

from rrls.envs import (
    TASKS,
    AntParamsBound,
    HalfCheetahParamsBound,
    HopperParamsBound,
    HumanoidStandupParamsBound,
    InvertedPendulumParamsBound,
    Walker2dParamsBound,
    get_uncertainty_set,
)
from rrls.uncertainty import UncertaintySet

# the paper's tables as data (a copy of ../shared/paper/tables.json kept with the tests)
TABLES = pathlib.Path(__file__).resolve().parent / "data" / "paper_tables.json"
SHARED = pathlib.Path(__file__).resolve().parents[2] / "shared" / "paper" / "tables.json"
PAPER_TASK = {
    "ant": "Ant",
    "halfcheetah": "HalfCheetah",
    "hopper": "Hopper",
    "humanoidstandup": "HumanoidStandup",
    "invertedpendulum": "InvertedPendulum",
    "walker": "Walker",
}


def test_mesh_includes_both_bounds_and_counts():
    box = UncertaintySet.from_bounds({"a": [0.1, 3.0], "b": [1.0, 2.0], "c": [0.0, 1.0]})
    mesh = box.mesh(10)
    assert mesh.shape == (1000, 3)
    np.testing.assert_array_equal(mesh[0], box.low)
    np.testing.assert_array_equal(mesh[-1], box.high)
    assert box.contains(mesh).all()
    np.testing.assert_array_equal(mesh[:10, 2], np.linspace(0.0, 1.0, 10))  # last varies fastest


def test_mesh_endpoint_false_is_the_original_arange():
    box = get_uncertainty_set("hopper", "1d")
    expected = np.arange(0.1, 3.0, (3.0 - 0.1) / 10)
    np.testing.assert_array_equal(box.mesh(10, endpoint=False)[:, 0], expected)
    assert box.mesh(10, endpoint=False)[:, 0].max() < 3.0  # the original's upper bound gap


def test_normalize_roundtrip_and_contains():
    box = get_uncertainty_set("walker", "3d")
    rng = np.random.default_rng(0)
    x = box.sample(rng, 50)
    np.testing.assert_allclose(box.denormalize(box.normalize(x)), x)
    np.testing.assert_array_equal(box.normalize(box.low), -np.ones(3))
    np.testing.assert_array_equal(box.normalize(box.high), np.ones(3))
    assert box.contains(box.sample(rng))
    assert not box.contains(box.high + 1e-9)


def test_sampling_is_seeded():
    box = get_uncertainty_set("ant", "3d")
    a = box.sample(np.random.default_rng(3))
    b = box.sample(np.random.default_rng(3))
    assert a == b and list(a) == list(box.names)
    with pytest.raises(TypeError):
        box.sample(np.random.RandomState(0))


def test_validation_and_repr():
    with pytest.raises(ValueError, match="low > high"):
        UncertaintySet.from_bounds({"a": [2.0, 1.0]})
    with pytest.raises(ValueError, match="finite"):
        UncertaintySet.from_bounds({"a": [0.0, float("inf")]})
    with pytest.raises(ValueError, match="exactly"):
        get_uncertainty_set("hopper", "2d").to_array({"worldfriction": 1.0})
    assert "torsomass=[0.1, 3]" in repr(get_uncertainty_set("hopper", "2d"))
    with pytest.raises(ValueError, match="valid tasks"):
        get_uncertainty_set("cartpole", "1d")
    with pytest.raises(ValueError, match="no uncertainty set"):
        get_uncertainty_set("invertedpendulum", "3d")


def test_nominal_points_come_from_the_model():
    box = get_uncertainty_set("hopper", "3d")
    np.testing.assert_allclose(box.nominal, [1.0, 3.6651914291880923, 4.057890510886818])
    assert get_uncertainty_set("hopper", "rarl").nominal.tolist() == [0.0, 0.0]


def test_compat_enums():
    assert HopperParamsBound.THREE_DIM.value == {
        "worldfriction": [0.1, 3.0],
        "torsomass": [0.1, 3.0],
        "thighmass": [0.1, 4.0],
    }
    assert not hasattr(InvertedPendulumParamsBound, "THREE_DIM")
    for enum in (AntParamsBound, HalfCheetahParamsBound, HumanoidStandupParamsBound):
        assert {m.name for m in enum} == {"ONE_DIM", "TWO_DIM", "THREE_DIM", "RARL"}
    assert Walker2dParamsBound.RARL.value["leftfootforce_y"] == [-3.0, 3.0]
    # the paper's HumanoidStandup 3D bounds (the original code swaps the last two)
    assert HumanoidStandupParamsBound.THREE_DIM.value["rightfootmass"] == [0.1, 5.0]
    assert HumanoidStandupParamsBound.THREE_DIM.value["leftthighmass"] == [0.1, 8.0]


@pytest.mark.skipif(not SHARED.exists(), reason="../shared/paper/tables.json not beside the repo")
def test_the_tests_copy_of_the_paper_tables_is_current():
    assert json.loads(TABLES.read_text()) == json.loads(SHARED.read_text())


def test_sets_and_names_match_the_paper_tables():
    tables = json.loads(TABLES.read_text())
    for key, paper in PAPER_TASK.items():  # the paper's tasks (not rrls's own, nor users')
        task = TASKS[key]
        m2td3 = tables["uncertainty_sets_m2td3"][paper]
        for d in ("1", "2", "3"):
            if d not in m2td3:
                assert f"{d}d" not in task.sets
                continue
            ours = {k: list(v) for k, v in task.sets[f"{d}d"].items()}
            assert ours == m2td3[d], (key, d)
        rarl = tables["uncertainty_sets_rarl_forces"]
        assert list(task.sets["rarl"]) == rarl[paper]
        assert all(v == tuple(rarl["_bounds"]) for v in task.sets["rarl"].values())
        names = tables["parameter_names_original_code"]
        # the original code's names come first; rrls's further kinds follow
        assert [s.name for s in task.params][: len(names[paper])] == names[paper]
        bodies = names["force_bodies"][paper]
        assert sorted({s.name.rsplit("force_", 1)[0] for s in task.forces}) == sorted(bodies)
        # the paper's (rounded) reference values agree with the nominal values of the model,
        # within 12 %: its InvertedPendulum cart (9.42) is lighter than Gymnasium v5's (10.47)
        box = get_uncertainty_set(key, "3d" if "3d" in task.sets else "2d")
        np.testing.assert_allclose(box.nominal, m2td3["reference"], rtol=0.12, atol=0.02)
