"""Domain randomization, the adversarial game, action-robust mixing, PettingZoo, vector envs."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from conftest import fixed_actions, rollout

import rrls  # noqa: F401
from rrls.envs import ForceHopper, HopperParamsBound, RobustHopper
from rrls.wrappers import (
    ConcatenateActions,
    DomainRandomization,
    DynamicAdversarial,
    ProbabilisticActionRobust,
)


def _dr_draws(env, seeds):
    return [env.reset(seed=s)[1]["randomized_params"] for s in seeds]


def test_domain_randomization_is_seeded_and_ignores_global_numpy_state():
    env = DomainRandomization(RobustHopper(), HopperParamsBound.THREE_DIM.value)
    np.random.seed(1)  # noqa: NPY002 - the point: global state must not matter
    first = [env.reset(seed=5)[1]["randomized_params"]] + [env.reset()[1]["randomized_params"]]
    np.random.seed(2)  # noqa: NPY002
    second = [env.reset(seed=5)[1]["randomized_params"]] + [env.reset()[1]["randomized_params"]]
    assert first == second
    assert first[0] != first[1]  # new parameters every episode
    assert _dr_draws(env, [6])[0] != first[0]


def test_domain_randomization_sets_what_it_draws_inside_the_bounds():
    env = gym.make("rrls/robust-hopper-domain-randomization-3d-v0")
    for seed in range(20):
        _, info = env.reset(seed=seed)
        draw = info["randomized_params"]
        for name, (lo, hi) in HopperParamsBound.THREE_DIM.value.items():
            assert lo <= draw[name] <= hi
            assert env.get_params()[name] == draw[name]


def test_domain_randomization_custom_fn_and_options_override():
    def corner(box, rng):
        return box.to_dict(box.high)

    env = DomainRandomization(RobustHopper(), HopperParamsBound.TWO_DIM.value, corner)
    env.reset(seed=0, options={"torsomass": 1.0})
    assert env.get_params()["worldfriction"] == 3.0 and env.get_params()["torsomass"] == 1.0


def test_dynamic_adversarial_maps_clips_and_negates():
    env = gym.make("rrls/robust-hopper-adversarial-3d-v0")
    inner = env.action_space.spaces[0]
    assert env.action_space.spaces[1].shape == (3,)
    nominal = env.get_params()
    env.reset(seed=0)
    _, r, _, _, info = env.step((np.zeros(3, np.float32), np.array([-1.0, 0.0, 5.0], np.float32)))
    assert info["adversarial_reward"] == -r
    p = env.get_params()
    assert p["worldfriction"] == pytest.approx(0.1)
    assert p["torsomass"] == pytest.approx(1.55)
    assert p["thighmass"] == pytest.approx(4.0)  # clipped to the upper bound
    env.reset()
    assert env.get_params() == nominal  # back to nominal at reset
    assert env.get_wrapper_attr("params_bound") == HopperParamsBound.THREE_DIM.value
    assert isinstance(inner, gym.spaces.Box)


def test_dynamic_adversarial_over_forces():
    env = gym.make("rrls/robust-hopper-adversarial-forces-v0")
    env.reset(seed=0)
    env.step((np.zeros(3, np.float32), np.array([1.0, -1.0], np.float32)))
    p = env.get_params()
    assert p["footforce_x"] == 3.0 and p["footforce_y"] == -3.0


def test_adversary_at_fixed_params_matches_the_plain_env():
    """An adversary that always plays the same point is the robust env at that point."""
    box = HopperParamsBound.TWO_DIM.value
    game = DynamicAdversarial(RobustHopper(), box)
    z = np.array([0.5, -0.25], np.float32)
    point = {k: float(v) for k, v in game.params_of(z).items()}
    actions = fixed_actions(game.action_space.spaces[0], 100)
    plain = RobustHopper(**point)
    obs_plain, r_plain, _ = rollout(plain, actions, seed=2)
    obs, _ = game.reset(seed=2)
    np.testing.assert_array_equal(obs, obs_plain[0])
    for t, a in enumerate(actions[: len(r_plain)]):
        obs, r, *_ = game.step((a, z))
        np.testing.assert_array_equal(obs, obs_plain[t + 1])
        assert r == r_plain[t]


def test_nr_mdp_mixing_follows_the_original_convention():
    env = ProbabilisticActionRobust(RobustHopper(), alpha=0.25)
    env.reset(seed=0)
    *_, info = env.step((np.ones(3, np.float32), -np.ones(3, np.float32)))
    np.testing.assert_allclose(info["executed_action"], 0.5)


def test_pr_mdp_is_seeded_and_picks_whole_actions():
    def executed(seed):
        env = ProbabilisticActionRobust(RobustHopper(), alpha=0.5, mode="pr")
        env.reset(seed=seed)
        out = []
        for _ in range(30):
            *_, term, trunc, info = env.step((np.ones(3, np.float32), -np.ones(3, np.float32)))
            out.append(info["executed_action"][0])
            if term or trunc:
                break
        return out

    a, b = executed(3), executed(3)
    assert a == b and set(a) == {1.0, -1.0}


def test_concatenate_actions_splits_back():
    env = ConcatenateActions(DynamicAdversarial(RobustHopper(), HopperParamsBound.TWO_DIM.value))
    assert env.action_space.shape == (5,)
    env.reset(seed=0)
    env.step(np.array([0, 0, 0, 1, -1], np.float32))
    assert env.get_params()["worldfriction"] == 3.0
    with pytest.raises(ValueError, match="shape"):
        env.step(np.zeros(4, np.float32))


@pytest.mark.parametrize(
    "env_id", ["rrls/robust-hopper-adversarial-2d-v0", "rrls/probabilistic-action-robust-walker-v0"]
)
def test_pettingzoo_view_passes_the_api_test(env_id):
    from pettingzoo.test import parallel_api_test

    from rrls.wrappers.pettingzoo import TwoPlayerParallelEnv

    game = TwoPlayerParallelEnv(gym.make(env_id))
    parallel_api_test(game, num_cycles=200)
    game.reset(seed=0)
    actions = {a: game.action_space(a).sample() for a in game.agents}
    _, rewards, *_ = game.step(actions)
    assert rewards["protagonist"] == -rewards["adversary"]


@pytest.mark.parametrize("mode", ["sync", "async"])
@pytest.mark.parametrize(
    "env_id", ["rrls/robust-hopper-v0", "rrls/robust-walker-domain-randomization-2d-v0"]
)
def test_vector_envs_run(env_id, mode):
    envs = gym.make_vec(env_id, num_envs=2, vectorization_mode=mode)
    obs, info = envs.reset(seed=0)
    assert obs.shape[0] == 2
    for _ in range(5):
        obs, *_ = envs.step(envs.action_space.sample())
    envs.close()


def test_sync_vector_env_of_robust_envs_with_different_params():
    envs = gym.vector.SyncVectorEnv(
        [lambda m=m: gym.make("rrls/robust-hopper-v0", torsomass=m) for m in (1.0, 5.0)]
    )
    obs, info = envs.reset(seed=[0, 0])
    np.testing.assert_array_equal(info["torsomass"], [1.0, 5.0])
    for _ in range(20):
        obs, *_ = envs.step(np.zeros((2, 3), np.float32))
    assert not np.array_equal(obs[0], obs[1])
    envs.close()


# -- bad input ----------------------------------------------------------------------------------
def test_unknown_parameter_lists_valid_names_and_changes_nothing():
    env = gym.make("rrls/robust-hopper-v0")
    before = env.get_params()
    with pytest.raises(ValueError, match="valid names: worldfriction, torsomass"):
        env.set_params(torsomass=1.0, torsomas=2.0)
    assert env.get_params() == before
    with pytest.raises(ValueError, match="unknown parameter"):
        env.reset(options={"footmas": 1.0})


@pytest.mark.parametrize(
    "params",
    [
        {"torsomass": float("nan")},
        {"torsomass": float("inf")},
        {"torsomass": 0.0},
        {"thighmass": -1.0},
        {"worldfriction": -0.1},
        {"torsomass": "heavy"},
    ],
)
def test_non_physical_values_are_refused_and_change_nothing(params):
    env = RobustHopper()
    before = env.get_params()
    mass = env.model.body_mass.copy()
    with pytest.raises(ValueError):
        env.set_params(footmass=1.0, **params)
    assert env.get_params() == before
    np.testing.assert_array_equal(env.model.body_mass, mass)


def test_forces_refuse_non_finite_and_constructor_checks():
    with pytest.raises(ValueError, match="finite"):
        ForceHopper(footforce_x=float("nan"))
    with pytest.raises(TypeError, match="physical parameters"):
        RobustHopper(torso_mass=1.0)


def test_bad_bounds_and_actions():
    with pytest.raises(ValueError, match="low > high"):
        DomainRandomization(RobustHopper(), {"torsomass": [3.0, 1.0]})
    with pytest.raises(ValueError, match="unknown parameter"):
        DynamicAdversarial(RobustHopper(), {"pole_mass": [1.0, 2.0]})
    env = gym.make("rrls/robust-hopper-adversarial-2d-v0")
    env.reset(seed=0)
    with pytest.raises(ValueError, match="adversary action must have shape"):
        env.step((np.zeros(3, np.float32), np.zeros(3, np.float32)))
    with pytest.raises(ValueError, match="pair"):
        env.step(np.zeros(5, np.float32))
    with pytest.raises(ValueError, match="alpha"):
        ProbabilisticActionRobust(RobustHopper(), alpha=1.5)
