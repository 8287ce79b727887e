"""Outside probes of ``register_task`` (issue 26): its bounds follow ``UncertaintySet.from_bounds``
and its key never shadows a built-in task's key or alias."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import rrls
from rrls import registry
from rrls.envs import get_uncertainty_set
from rrls.params import mass_params
from rrls.registry import TASKS
from rrls.uncertainty import UncertaintySet

PARAMS = mass_params({"torso": "torso", "thigh": "thigh"})


def _register(key: str, bounds: object, **kw: object) -> object:
    return rrls.register_task(
        key, "Hopper-v5", name=f"Probe{key.title()}", params=PARAMS,
        sets={"1d": {"torsomass": bounds}}, check=False, **kw,
    )  # fmt: skip


@pytest.mark.parametrize(
    "bounds", ["12", b"12", (1.0,), (1.0, 2.0, 3.0), (2.0, 1.0), (1.0, np.nan), ("a", 2.0), 3.0]
)
def test_bounds_are_refused_exactly_where_from_bounds_refuses_them(bounds):
    with pytest.raises((ValueError, TypeError)) as expected:
        UncertaintySet.from_bounds({"torsomass": bounds})
    with pytest.raises(ValueError) as got:
        _register("probebounds", bounds)
    assert "probebounds" not in TASKS
    assert str(expected.value) in str(got.value)  # the same rule, named the same way
    assert "'probebounds'" in str(got.value) and "'1d'" in str(got.value)


def test_bounds_from_bounds_accepts_are_accepted():
    for bounds in ([1, 2], np.array([1.0, 2.0]), (np.float32(1.0), 2)):
        spec = _register("probeok", bounds)
        assert spec.sets["1d"] == {"torsomass": (1.0, 2.0)}
        registry.unregister_task("probeok")


def test_a_key_that_is_a_built_in_alias_is_refused():
    with pytest.raises(ValueError, match="'idp' is an alias of the task 'inverteddoublependulum'"):
        _register("idp", (1.0, 2.0))
    assert "rrls/robust-idp-v0" not in gym.registry
    assert rrls.tasks.get_task("idp").key == "inverteddoublependulum"
    assert (
        get_uncertainty_set("idp", "1d").names
        == get_uncertainty_set("inverteddoublependulum", "1d").names
    )


def test_a_built_in_task_is_never_replaced_nor_unregistered():
    hopper = TASKS["hopper"]
    with pytest.raises(ValueError, match="'hopper' is built into rrls"):
        rrls.register_task("hopper", "Hopper-v5", params=PARAMS, check=False, replace=True)
    with pytest.raises(ValueError, match="built into rrls"):
        registry.unregister_task("hopper")
    assert TASKS["hopper"] is hopper
    # re-declaring a built-in exactly as it is stays a no-op
    again = rrls.register_task(
        "hopper", hopper.v5_id, name=hopper.name, planar=hopper.planar, params=hopper.params,
        forces=hopper.forces, sets=hopper.sets, aliases=hopper.aliases,
        max_episode_steps=hopper.max_episode_steps, paper_env=hopper.paper_id, check=False,
    )  # fmt: skip
    assert again is hopper


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_a_non_finite_bound_names_its_parameter(bad):
    with pytest.raises(ValueError) as got:
        _register("probenan", (1.0, bad))
    assert "probenan" not in TASKS
    assert "bounds must be finite: torsomass got [1.0, " in str(got.value)
