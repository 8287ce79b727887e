"""rrls's own tasks (Humanoid, Swimmer, InvertedDoublePendulum, Reacher, Pusher): ids, bit-identical
nominal physics, every set parameter changes the trajectory, sets hold the nominal point,
evaluation rows equal the plain loop, copies, Gymnasium's checker."""

from __future__ import annotations

import pickle

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

from rrls.envs import FORCE_ENVS, ROBUST_ENVS, get_uncertainty_set
from rrls.evaluation import evaluate
from rrls.params import body_id
from rrls.tasks import TASKS

NEW = {
    "humanoid": "Humanoid-v5",
    "swimmer": "Swimmer-v5",
    "inverteddoublependulum": "InvertedDoublePendulum-v5",
    "reacher": "Reacher-v5",
    "pusher": "Pusher-v5",
}


def _actions(space, n, seed=0):
    rng = np.random.default_rng(seed)
    return rng.uniform(space.low, space.high, (n, *space.shape)).astype(space.dtype)


def _rollout(env, actions, seed=0):
    obs, _ = env.reset(seed=seed)
    out, rewards = [obs], []
    for a in actions:
        obs, r, term, trunc, _ = env.step(a)
        out.append(obs)
        rewards.append(r)
        if term or trunc:
            break
    return np.array(out), np.array(rewards)


@pytest.mark.parametrize("task", NEW)
def test_ids_make_and_nominal_is_bit_identical_to_v5(task):
    spec = TASKS[task]
    assert spec.v5_id == NEW[task]
    assert spec.max_episode_steps == gym.spec(NEW[task]).max_episode_steps
    plain, robust = gym.make(NEW[task]), gym.make(f"rrls/robust-{task}-v0")
    actions = _actions(plain.action_space, 40)
    a, ra = _rollout(plain, actions, seed=3)
    b, rb = _rollout(robust, actions, seed=3)
    np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(ra, rb)
    ids = [f"rrls/force-{task}-v0", f"rrls/robust-{task}-adversarial-forces-v0"]
    ids += [f"rrls/robust-{task}-adversarial-{d}-v0" for d in ("1d", "2d", "3d")]
    ids += [f"rrls/robust-{task}-domain-randomization-{d}-v0" for d in ("1d", "2d", "3d")]
    ids += [f"rrls/probabilistic-action-robust-{task}-v0"]
    for env_id in ids:
        env = gym.make(env_id)
        env.reset(seed=0)
        env.step(env.action_space.sample())


@pytest.mark.parametrize("task", NEW)
def test_every_set_parameter_changes_the_trajectory(task):
    cls = ROBUST_ENVS[task]
    actions = _actions(cls().action_space, 60)
    ref, _ = _rollout(cls(), actions)
    names = {n for s in TASKS[task].sets.values() for n in s if "force" not in n}
    for name in sorted(names):
        env = cls()
        low, high = TASKS[task].sets["3d"].get(name) or next(
            b[name] for b in TASKS[task].sets.values() if name in b
        )
        env.set_params(**{name: high if env.get_params(kinds="all")[name] != high else low})
        spec = next(s for s in cls.param_specs if s.name == name)
        if spec.field == "body_mass":  # reaches the named body
            b = body_id(env.model, spec.target)
            assert env.model.body_mass[b] == env.get_params(kinds="all")[name]
        obs, _ = _rollout(env, actions)
        n = min(len(obs), len(ref))
        assert not np.array_equal(obs[:n], ref[:n]), (task, name)


@pytest.mark.parametrize("task", NEW)
def test_sets_are_rrls_own_and_hold_the_nominal_point(task):
    for name in ("1d", "2d", "3d", "rarl"):
        box = get_uncertainty_set(task, name)
        assert box.dim == int(name[0]) if name != "rarl" else box.family == "force"
        assert box.contains(box.nominal), (task, name, box)
    force = FORCE_ENVS[task]()
    for n in TASKS[task].sets["rarl"]:
        force.set_params(**{n: 0.05})
        assert force.get_params()[n] == 0.05


@pytest.mark.parametrize("task", ["swimmer", "reacher"])
def test_evaluation_rows_equal_the_plain_loop(task):
    space = gym.make(f"rrls/robust-{task}-v0").action_space

    def policy(obs):
        return np.tile(np.linspace(space.low, space.high, 3)[1] * 0.5 + 0.1, (len(obs), 1))

    result = evaluate(policy, task, "1d", mesh=2, episodes=1, workers=1, max_episode_steps=30)
    for _, row in result.episodes.iterrows():
        env = gym.make(f"rrls/robust-{task}-v0")
        name = result.param_names[0]
        env.set_params(**{name: row[name]})
        obs, _ = env.reset(seed=int(row["seed"]))
        total = 0.0
        for _ in range(30):
            obs, r, term, trunc, _ = env.step(policy(obs[None])[0])
            total += r
            if term or trunc:
                break
        assert total == row["return"]


@pytest.mark.parametrize("task", NEW)
def test_copies_and_gymnasium_checker(task):
    env = ROBUST_ENVS[task]()
    first = next(iter(TASKS[task].sets["1d"]))
    timestep = env.get_params(kinds="all")["timestep"]
    env.set_params(**{first: TASKS[task].sets["1d"][first][1], "timestep": timestep * 0.9})
    twin = pickle.loads(pickle.dumps(env))
    assert twin.get_params(kinds="all") == env.get_params(kinds="all")
    check_env(ROBUST_ENVS[task](), skip_render_check=True)
    check_env(FORCE_ENVS[task](), skip_render_check=True)
