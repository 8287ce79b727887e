"""Evaluation meshes: lazy environment sets and point arrays."""

from __future__ import annotations

import numpy as np
import pytest

from rrls import generate_evaluation_set
from rrls.envs import ForceHopper, HopperParamsBound, RobustHopper
from rrls.evaluation import default_evaluation_set, evaluation_points


def test_generate_evaluation_set_is_lazy_and_reaches_both_bounds():
    envs = generate_evaluation_set(RobustHopper, HopperParamsBound.THREE_DIM.value, 10)
    assert len(envs) == 1000 and envs.points.shape == (1000, 3)
    last = envs[-1]
    assert last.get_params()["thighmass"] == 4.0 and last.get_params()["worldfriction"] == 3.0
    assert [e.get_params()["thighmass"] for e in envs[:2]] == [0.1, pytest.approx(0.1 + 3.9 / 9)]


def test_endpoint_false_is_the_original_mesh():
    envs = generate_evaluation_set(
        RobustHopper, HopperParamsBound.ONE_DIM.value, 10, endpoint=False
    )
    np.testing.assert_array_equal(envs.points[:, 0], np.arange(0.1, 3.0, 0.29))


def test_points_without_environments_and_named_defaults():
    pts = evaluation_points("walker", "2d", mesh=4)
    assert pts.shape == (16, 2)
    nominal = evaluation_points("hopper", "nominal")
    assert nominal.shape == (1, 0)  # one point, no parameter set: the model as shipped
    forces = default_evaluation_set("hopper", "rarl", mesh=3)
    assert forces.modified_env is ForceHopper and len(forces) == 9
    assert forces[0].get_params()["footforce_x"] == -3.0
