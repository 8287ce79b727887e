"""Every parameter kind (gravity, joint damping / armature / dry friction, actuator gear,
per-body friction, centre-of-mass offsets, timestep) on every task: each row writes exactly its
MuJoCo field, changes the trajectory, is refused out of range without changing anything, is
restored exactly by reset_params and survives copies."""

from __future__ import annotations

import copy
import pickle

import gymnasium as gym
import numpy as np
import pytest

from rrls.envs import ROBUST_ENVS, RobustAnt, RobustHopper
from rrls.params import FIELDS
from rrls.tasks import TASKS

PRIMARY = (
    "body_mass",
    "body_inertia",
    "body_ipos",
    "geom_friction",
    "dof_damping",
    "dof_armature",
    "dof_frictionloss",
    "actuator_gear",
)
DERIVED = ("body_subtreemass", "dof_M0", "dof_invweight0", "actuator_acc0", "actuator_length0")
NEW_FIELDS = {
    "body_friction",
    "body_ipos",
    "dof_damping",
    "dof_armature",
    "dof_frictionloss",
    "actuator_gear",
    "opt_gravity",
    "opt_timestep",
}


def snapshot(model) -> dict[str, np.ndarray]:
    out = {f: getattr(model, f).copy() for f in PRIMARY + DERIVED}
    out["gravity"] = model.opt.gravity.copy()
    out["timestep"] = np.array(model.opt.timestep)
    return out


def changed(before, after) -> dict[str, list]:
    return {
        k: np.argwhere(before[k] != after[k]).tolist()
        for k in before
        if not np.array_equal(before[k], after[k])
    }


def new_value(spec, nominal: float) -> float:
    if spec.field == "body_ipos":
        return 0.05
    if spec.field == "opt_timestep":
        return nominal * 1.25
    return nominal * 1.5 + 0.1


def expected_cells(env, spec) -> dict[str, list]:
    """The primary model cells the row must write (and nothing else)."""
    idx = env._rows[spec.name][1]
    field = spec.field
    if field == "body_friction":
        return {"geom_friction": [[int(g), 0] for g in idx]}
    if field == "body_ipos":
        return {"body_ipos": [[int(idx[0]), spec.component]]}
    if field == "actuator_gear":
        return {"actuator_gear": [[int(idx[0]), 0]]}
    if field.startswith("dof_"):
        return {field: [[int(idx[0])]]}
    if field == "opt_gravity":
        return {"gravity": [[2]]}
    return {"timestep": [[]]}


@pytest.mark.parametrize("task", sorted(TASKS))
def test_every_new_row_writes_exactly_its_field_and_reset_restores_bitwise(task):
    cls = ROBUST_ENVS[task]
    env = cls()
    fresh = snapshot(env.model)
    nominal = env.get_params(kinds="all")
    rows = [s for s in cls.param_specs if s.field in NEW_FIELDS]
    if task in ("ant", "halfcheetah", "hopper", "humanoidstandup", "invertedpendulum", "walker"):
        assert {s.field for s in rows} == NEW_FIELDS  # every kind on every paper task
    for spec in rows:
        value = new_value(spec, nominal[spec.name])
        env.set_params(**{spec.name: value})
        assert env.get_params(kinds="all")[spec.name] == pytest.approx(value, rel=1e-12, abs=1e-15)
        now = snapshot(env.model)
        diff = {k: v for k, v in changed(fresh, now).items() if k not in DERIVED}
        assert diff == expected_cells(env, spec), spec.name
        if spec.field == "dof_armature":  # derived constants refreshed (mj_setConst)
            assert "dof_M0" in changed(fresh, now), spec.name
        env.reset_params()
        assert not changed(fresh, snapshot(env.model)), spec.name
        assert env.get_params(kinds="all") == nominal


def _rollout(env, actions, seed=0):
    obs, _ = env.reset(seed=seed)
    out, rewards = [obs], []
    for a in actions:
        obs, r, term, _, _ = env.step(a)
        out.append(obs)
        rewards.append(r)
        if term:
            break
    return np.array(out), np.array(rewards)


KIND_CASES = [
    ("torsocom_y", 0.05),  # Ant: out-of-plane offsets exist on 3-D tasks
    ("hip1gear", 60.0),
    ("footfriction", 0.3),
    ("thighcom_x", 0.05),
    ("legcom_z", -0.05),
    ("thighdamping", 5.0),
    ("thigharmature", 0.1),
    ("thighfrictionloss", 2.0),
    ("thighgear", 120.0),
    ("gravity", 5.0),
    ("timestep", 0.0025),
]


@pytest.mark.parametrize("name, value", KIND_CASES)
def test_each_kind_changes_the_trajectory(name, value):
    cls = RobustAnt if name in ("torsocom_y", "hip1gear") else RobustHopper
    rng = np.random.default_rng(0)
    actions = rng.uniform(-1, 1, size=(80, cls().action_space.shape[0]))
    ref_obs, ref_rew = _rollout(cls(), actions)
    env = cls()
    env.set_params(**{name: value})
    obs, rew = _rollout(env, actions)
    n = min(len(obs), len(ref_obs))
    assert not np.array_equal(obs[:n], ref_obs[:n]), name
    if name == "timestep":  # Gymnasium's dt = frame_skip * timestep
        assert env.dt == pytest.approx(4 * 0.0025)
    # the constructor keyword is the same as set_params
    np.testing.assert_array_equal(_rollout(cls(**{name: value}), actions)[0], obs)
    # back at nominal, the trajectory is the reference again, bit for bit
    env.reset_params()
    again, again_rew = _rollout(env, actions)
    np.testing.assert_array_equal(again, ref_obs)
    np.testing.assert_array_equal(again_rew, ref_rew)


def test_three_dimensional_tasks_have_three_com_axes_and_planar_two():
    names = set(RobustAnt.param_names())
    assert {"torsocom_x", "torsocom_y", "torsocom_z", "hip1damping", "ankle4gear"} <= names
    assert "torsocom_y" not in RobustHopper.param_names()


@pytest.mark.parametrize(
    "params, needle",
    [
        ({"thighdamping": -1.0}, "thighdamping is a damping and must be >= 0"),
        ({"thigharmature": -0.1}, "thigharmature is an armature and must be >= 0"),
        ({"thighfrictionloss": -0.1}, "must be >= 0"),
        ({"thighgear": -5.0}, "thighgear is a gear and must be >= 0"),
        ({"footfriction": -0.1}, "footfriction is a friction and must be >= 0"),
        ({"thighcom_x": 20.0}, "thighcom_x must be <= 10"),
        ({"gravity": -9.81}, "gravity is a gravity and must be >= 0"),
        ({"timestep": 0.0}, "timestep is a timestep and must be > 0"),
        ({"timestep": 0.5}, "timestep must be <= 0.1"),
        ({"timestep": float("nan")}, "timestep must be finite"),
        ({"torsomass": 2.0, "thighdamping": -1.0}, "thighdamping"),  # nothing applied
    ],
)
def test_out_of_range_values_are_refused_and_change_nothing(params, needle):
    env = RobustHopper()
    before, values = snapshot(env.model), env.get_params(kinds="all")
    with pytest.raises(ValueError, match=needle):
        env.set_params(**params)
    assert not changed(before, snapshot(env.model))
    assert env.get_params(kinds="all") == values


def test_overlapping_friction_rows_report_what_the_model_holds_and_copies_replay_in_order():
    env = RobustHopper()
    env.set_params(footfriction=0.5)
    env.set_params(worldfriction=1.2)  # every geom, the foot included
    assert env.get_params(kinds="all")["footfriction"] == 1.2
    twin = pickle.loads(pickle.dumps(env))
    np.testing.assert_array_equal(twin.model.geom_friction, env.model.geom_friction)
    assert twin.get_params(kinds="all") == env.get_params(kinds="all")


@pytest.mark.parametrize("how", ["deepcopy", "pickle"])
def test_copies_keep_every_kind_and_continue_bit_identically(how):
    env = gym.make("rrls/robust-hopper-v0")
    params = {"timestep": 0.003, "thighdamping": 2.0, "legcom_x": 0.02, "footgear": 150.0}
    params |= {"gravity": 8.0, "thigharmature": 0.5, "footfriction": 1.1, "legfrictionloss": 0.3}
    env.reset(seed=1, options=params)
    actions = np.random.default_rng(1).uniform(-1, 1, size=(40, 3))
    for a in actions[:20]:
        env.step(a)
    twin = copy.deepcopy(env) if how == "deepcopy" else pickle.loads(pickle.dumps(env))
    assert twin.get_params(kinds="all") == env.get_params(kinds="all")
    assert not changed(snapshot(env.unwrapped.model), snapshot(twin.unwrapped.model))
    for a in actions[20:]:
        s1, s2 = env.step(a), twin.step(a)
        np.testing.assert_array_equal(s1[0], s2[0])
        assert s1[1:4] == s2[1:4]


def test_field_table_lists_units_and_ranges():
    for name, info in FIELDS.items():
        assert info.units and info.mujoco and info.target, name
        assert info.low < info.high, name


def test_docs_document_every_kind():
    from pathlib import Path

    page = (Path(__file__).resolve().parents[1] / "docs" / "concepts.md").read_text()
    table = page.split("\n## Parameter kinds", 1)[1].split("\n\n", 2)[1]
    for name, info in FIELDS.items():
        field = info.mujoco.split("[")[0].split(" ")[0]
        assert f"`{field}" in table, (name, field)
        assert info.units.split(" ")[0] in table, (name, info.units)


def test_info_reports_masses_always_and_other_kinds_once_set():
    env = RobustHopper()
    _, info = env.reset(seed=0)
    assert info["torsomass"] == env.get_params()["torsomass"] and "worldfriction" in info
    assert "thighdamping" not in info  # every kind in every step's info would cost ~10 %
    env.set_params(thighdamping=2.5)
    _, _, _, _, info = env.step(env.action_space.sample())
    assert info["thighdamping"] == 2.5
    _, info = env.reset(options={"gravity": 7.0})
    assert info["gravity"] == 7.0 and info["thighdamping"] == 2.5
    env.reset_params()
    _, info = env.reset(seed=1)
    assert "gravity" not in info


def test_part_friction_is_inert_below_the_friction_it_touches_as_documented():
    """MuJoCo takes the larger friction of a contact's two geoms: Hopper's foot below the
    floor's 1.0 changes nothing, unless the floor is lowered first (docs/concepts.md, tasks.md)."""
    from rrls.envs import RobustHopper

    actions = np.random.default_rng(0).uniform(-1, 1, (300, 3))

    def qpos(**params):
        env = RobustHopper(**params)
        env.reset(seed=0)
        for a in actions:
            if env.step(a)[2]:
                break
        return env.data.qpos.copy()

    inert = [qpos(footfriction=f) for f in (0.1, 0.5, 1.0)]
    assert all(np.array_equal(q, inert[-1]) for q in inert)
    acting = [qpos(worldfriction=0.1, footfriction=f) for f in (0.1, 0.9)]
    assert not np.array_equal(*acting)
