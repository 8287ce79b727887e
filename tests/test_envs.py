"""Robust and force envs: identity with v5, every parameter reaches its body, copies, checks."""

from __future__ import annotations

import copy
import pickle

import gymnasium as gym
import mujoco
import numpy as np
import pytest
from conftest import TASK_KEYS, fixed_actions, rollout
from gymnasium.utils.env_checker import check_env

import rrls  # noqa: F401  (registers the ids)
from rrls.envs import FORCE_ENVS, ROBUST_ENVS, TASKS, RobustAnt, RobustHopper, RobustWalker2d
from rrls.params import body_id

V5 = {k: t.v5_id for k, t in TASKS.items()}


def _body_name(model, i):
    return mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, i)


@pytest.mark.parametrize("task", TASK_KEYS)
def test_nominal_is_bit_identical_to_v5(task):
    ours, plain = gym.make(f"rrls/robust-{task}-v0"), gym.make(V5[task])
    assert ours.spec.max_episode_steps == plain.spec.max_episode_steps == 1000
    actions = fixed_actions(plain.action_space, 300)
    for seed in (0, 7):
        o1, r1, f1 = rollout(ours, actions, seed)
        o2, r2, f2 = rollout(plain, actions, seed)
        np.testing.assert_array_equal(o1, o2)
        np.testing.assert_array_equal(r1, r2)
        assert f1 == f2


def test_truncation_at_1000_steps_like_v5():
    ours, plain = gym.make("rrls/robust-halfcheetah-v0"), gym.make("HalfCheetah-v5")
    actions = fixed_actions(plain.action_space, 1000)
    o1, r1, f1 = rollout(ours, actions, 3)
    o2, r2, f2 = rollout(plain, actions, 3)
    assert len(f1) == 1000 and f1[-1] == (False, True) and f1 == f2
    np.testing.assert_array_equal(o1, o2)


@pytest.mark.parametrize("task", TASK_KEYS)
def test_every_mass_reaches_its_named_body_and_changes_the_trajectory(task):
    cls = ROBUST_ENVS[task]
    env = cls()
    model = env.model
    actions = fixed_actions(env.action_space, 60)
    ref, _, _ = rollout(env, actions)
    for spec in cls.param_specs:
        if spec.field != "body_mass":
            continue
        env = cls()
        b = body_id(env.model, spec.target)
        nominal = env.get_params()[spec.name]
        assert nominal == model.body_mass[b]  # read from the compiled model
        env.set_params(**{spec.name: nominal * 1.7})
        expected = env.unwrapped.model.body_mass.copy()
        changed = np.flatnonzero(expected != model.body_mass)
        assert changed.tolist() == [b], spec.name
        if "/" in spec.target:  # Ant's unnamed ankle: the child of the named aux body
            parent = spec.target.split("/")[0]
            assert _body_name(env.model, env.model.body_parentid[b]) == parent
            assert _body_name(env.model, b) is None
        else:
            assert _body_name(env.model, b) == spec.target
        # derived constants refreshed (mj_setConst)
        assert env.model.body_subtreemass[0] == pytest.approx(expected.sum())
        obs, _, _ = rollout(env, actions)
        assert not np.array_equal(obs[: len(ref)], ref[: len(obs)]), spec.name


def test_ant_parameter_names_follow_the_original_layout():
    env = RobustAnt()
    masses = [s for s in env.param_specs if s.field == "body_mass"]
    names = {s.name: _body_name(env.model, body_id(env.model, s.target)) for s in masses}
    assert names["frontleftlegmass"] == "front_left_leg"
    assert names["frontleftlegauxmass"] == "aux_1"
    assert names["backrightlegauxmass"] == "aux_4"
    ankle = body_id(env.model, "aux_1/child")
    assert env.model.body_parentid[ankle] == body_id(env.model, "aux_1")


def test_inverted_pendulum_masses_are_not_swapped():
    env = ROBUST_ENVS["invertedpendulum"](polemass=20.0, cartmass=3.0)
    m = env.model
    assert m.body_mass[body_id(m, "pole")] == 20.0
    assert m.body_mass[body_id(m, "cart")] == 3.0


@pytest.mark.parametrize("cls", [RobustHopper, RobustWalker2d])
def test_worldfriction_changes_every_contact(cls):
    actions = fixed_actions(cls().action_space, 200)
    trajectories = []
    for mu in (0.3, 1.0, 1.5):
        env = cls(worldfriction=mu)
        assert np.all(env.model.geom_friction[:, 0] == mu)
        assert env.get_params()["worldfriction"] == mu
        trajectories.append(rollout(env, actions)[0])
    for i in range(3):
        for j in range(i + 1, 3):
            n = min(len(trajectories[i]), len(trajectories[j]))
            assert not np.array_equal(trajectories[i][:n], trajectories[j][:n])


def test_hopper_nominal_friction_is_the_floor_value_and_reset_params_restores_exactly():
    env = RobustHopper()
    assert env.get_params()["worldfriction"] == 1.0  # the paper's reference, not 0.7
    friction0 = env.model.geom_friction.copy()
    env.set_params(worldfriction=0.5, torsomass=1.0)
    env.reset_params()
    np.testing.assert_array_equal(env.model.geom_friction, friction0)
    assert env.get_params() == RobustHopper().get_params()


def test_scale_inertia_option():
    plain, scaled = RobustHopper(torsomass=7.33), RobustHopper(torsomass=7.33, scale_inertia=True)
    b = body_id(plain.model, "torso")
    ref = RobustHopper().model.body_inertia[b]
    np.testing.assert_array_equal(plain.model.body_inertia[b], ref)
    np.testing.assert_allclose(scaled.model.body_inertia[b], ref * 7.33 / 3.6651914291880923)


def test_set_params_mid_episode_does_not_disturb_the_state():
    """mj_setConst works on scratch data: setting the nominal mass mid-episode changes nothing."""
    env, ref = RobustHopper(), RobustHopper()
    actions = fixed_actions(env.action_space, 100)
    env.reset(seed=1), ref.reset(seed=1)
    nominal = env.get_params()["torsomass"]
    for a in actions:
        env.set_params(torsomass=nominal)
        o1, *_ = env.step(a)
        o2, *_ = ref.step(a)
        np.testing.assert_array_equal(o1, o2)


@pytest.mark.parametrize("task", TASK_KEYS)
def test_every_force_writes_its_body_axis(task):
    cls = FORCE_ENVS[task]
    env = cls()
    planar = TASKS[task].planar
    for spec in cls.param_specs:
        env.set_params(**{spec.name: 2.5})
        b = body_id(env.model, spec.target)
        axis = {"x": 0, "y": 2 if planar else 1, "z": 2}[spec.name[-1]]
        assert env.data.xfrc_applied[b, axis] == 2.5, spec.name
        env.set_params(**{spec.name: 0.0})
    assert not env.data.xfrc_applied.any()


@pytest.mark.parametrize("task", TASK_KEYS)
def test_every_rarl_force_changes_the_trajectory(task):
    cls = FORCE_ENVS[task]
    actions = fixed_actions(cls().action_space, 40)
    ref, _, _ = rollout(cls(), actions)
    for name in TASKS[task].sets["rarl"]:
        obs, _, _ = rollout(cls(), actions, reset_options={name: 3.0})
        n = min(len(obs), len(ref))
        assert not np.array_equal(obs[:n], ref[:n]), name


def test_planar_z_is_an_alias_of_y():
    env = FORCE_ENVS["hopper"]()
    env.set_params(footforce_z=1.25)
    assert env.get_params(kinds="all")["footforce_y"] == 1.25
    assert "footforce_z" not in env.get_params(kinds="all")
    # the original's keys by default (its ForceHopper lists _x, _y, _z of every part)
    assert env.get_params()["footforce_z"] == 1.25


def test_forces_persist_across_reset_and_act_from_the_first_step():
    cls = FORCE_ENVS["hopper"]
    action = np.zeros(3, dtype=np.float32)
    plain = cls()
    plain.reset(seed=0)
    o_plain, *_ = plain.step(action)
    env = cls()
    env.reset(seed=0, options={"torsoforce_x": 3.0})
    o_force, *_ = env.step(action)
    assert not np.array_equal(o_plain, o_force)
    b = body_id(env.model, "torso")
    for _ in range(3):
        env.reset()
        assert env.data.xfrc_applied[b, 0] == 3.0
        assert env.get_params()["torsoforce_x"] == 3.0


@pytest.mark.parametrize("task", TASK_KEYS)
@pytest.mark.parametrize("how", ["deepcopy", "pickle"])
def test_copies_continue_bit_identically(task, how):
    env = gym.make(f"rrls/robust-{task}-v0")
    actions = fixed_actions(env.action_space, 60)
    name = ROBUST_ENVS[task].param_specs[-1].name
    env.reset(seed=4, options={name: 1.3 * env.get_params(kinds="all")[name]})
    for a in actions[:30]:
        env.step(a)
    twin = copy.deepcopy(env) if how == "deepcopy" else pickle.loads(pickle.dumps(env))
    assert twin.get_params(kinds="all") == env.get_params(kinds="all")
    for a in actions[30:]:
        s1, s2 = env.step(a), twin.step(a)
        np.testing.assert_array_equal(s1[0], s2[0])
        assert s1[1:4] == s2[1:4]
    # the generators were copied too: the next reset is the same
    np.testing.assert_array_equal(env.reset()[0], twin.reset()[0])


def test_force_env_copy_keeps_forces():
    env = FORCE_ENVS["walker"](legforce_x=2.0)
    env.reset(seed=0)
    twin = pickle.loads(pickle.dumps(env))
    assert twin.get_params()["legforce_x"] == 2.0
    np.testing.assert_array_equal(twin.data.xfrc_applied, env.data.xfrc_applied)


@pytest.mark.parametrize("task", TASK_KEYS)
@pytest.mark.parametrize("kind", ["robust", "force"])
def test_gymnasium_env_checker_passes(task, kind):
    cls = (ROBUST_ENVS if kind == "robust" else FORCE_ENVS)[task]
    check_env(cls(), skip_render_check=True)


@pytest.mark.parametrize("task", ["hopper", "ant"])
def test_seeds_reproduce(task):
    actions = fixed_actions(gym.make(V5[task]).action_space, 50)
    a = rollout(gym.make(f"rrls/robust-{task}-v0"), actions, seed=11)[0]
    b = rollout(gym.make(f"rrls/robust-{task}-v0"), actions, seed=11)[0]
    c = rollout(gym.make(f"rrls/robust-{task}-v0"), actions, seed=12)[0]
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a[0], c[0])


def test_info_carries_the_current_params():
    env = gym.make("rrls/robust-hopper-v0", torsomass=2.0)
    _, info = env.reset(seed=0)
    assert info["torsomass"] == 2.0
    env.set_params(thighmass=1.0)
    *_, info = env.step(env.action_space.sample())
    assert info["thighmass"] == 1.0 and info["torsomass"] == 2.0


def test_an_xml_file_is_compiled_once_and_every_env_owns_an_identical_copy(tmp_path):
    import shutil

    def mjb(model):  # the whole model, as MuJoCo saves it
        buf = np.zeros(mujoco.mj_sizeModel(model), np.uint8)
        mujoco.mj_saveModel(model, None, buf)
        return buf.tobytes()

    cls = RobustHopper
    a, b = cls(), cls()
    assert mjb(a.model) == mjb(b.model) == mjb(mujoco.MjModel.from_xml_path(a.fullpath))
    b.set_params(torsomass=9.0)
    assert b.model.body_mass[1] == 9.0 and a.model.body_mass[1] != 9.0  # no shared buffers
    assert mjb(cls().model) == mjb(a.model)  # the cached model is the compiled one, unchanged

    # an edited file is compiled again
    xml = tmp_path / "hopper.xml"
    shutil.copy(a.fullpath, xml)
    first = cls(xml_file=str(xml))
    xml.write_text(xml.read_text().replace('timestep="0.002"', 'timestep="0.003"', 1))
    edited = cls(xml_file=str(xml))
    assert first.model.opt.timestep == 0.002 and edited.model.opt.timestep == 0.003
