"""Rate-limited adversaries in evaluation, and rrls's earlier target-point game (``rate_game=
"target"``); TC-RMDP's own game as a wrapper: ``tests/test_tc_rmdp.py``."""

from __future__ import annotations

import numpy as np
import pytest

import rrls
from rrls.envs import HopperParamsBound, RobustHopper
from rrls.evaluation import MLPPolicy, evaluate_dynamic, evaluate_run_dynamic, make_dynamic_env
from rrls.uncertainty import UncertaintySet
from rrls.wrappers import DynamicAdversarial


@pytest.mark.parametrize("limit", [0.0, 0.05, 0.3])
def test_rate_limit_holds_at_every_step(limit):
    box = UncertaintySet.from_bounds(HopperParamsBound.THREE_DIM.value)
    game = DynamicAdversarial(RobustHopper(), box, rate_limit=limit, rate_game="target")
    rng = np.random.default_rng(0)
    _, info = game.reset(seed=0)
    before = box.normalize(box.to_array(game.get_params()))
    assert np.array_equal(before, info["normalized_params"])
    moved = 0.0
    for t in range(200):
        target = rng.choice([-1.0, 1.0], size=3)  # bang-bang: always far from where it is
        _, _, term, trunc, info = game.step((np.zeros(3), target))
        now = box.normalize(box.to_array(game.get_params()))
        step = np.abs(now - before).max()
        assert step <= limit + 1e-9, (t, step)
        assert box.contains(game.get_params())
        np.testing.assert_allclose(now, info["normalized_params"], atol=1e-9)
        moved = max(moved, step)
        before = now
        if term or trunc:
            break
    if limit > 0:
        assert moved > 0.5 * limit  # the adversary does move


def test_an_unbinding_rate_limit_plays_the_unlimited_game():
    box = HopperParamsBound.TWO_DIM.value
    free = DynamicAdversarial(RobustHopper(), box)
    limited = DynamicAdversarial(RobustHopper(), box, rate_limit=2.0, rate_game="target")
    rng = np.random.default_rng(1)
    free.reset(seed=3)
    limited.reset(seed=3)
    for _ in range(50):
        pair = (rng.uniform(-1, 1, 3), rng.uniform(-1, 1, 2))
        a, b = free.step(pair), limited.step(pair)
        assert np.array_equal(a[0], b[0]) and a[1] == b[1]
        assert free.get_params() == limited.get_params()


@pytest.mark.parametrize("game", ["tc", "target"])
@pytest.mark.parametrize("bad", [-0.1, np.nan, np.inf, "fast", True])
def test_bad_rate_limits_are_refused(bad, game):
    units = "raw parameter units" if game == "tc" else "normalised units"
    with pytest.raises(ValueError, match=f"rate_limit must be a finite number >= 0 \\({units}"):
        DynamicAdversarial(
            RobustHopper(), HopperParamsBound.ONE_DIM.value, rate_limit=bad, rate_game=game
        )


@pytest.mark.parametrize("context", [False, True])
def test_dynamic_evaluation_against_a_target_game_adversary_equals_the_plain_loop(context):
    limit = 0.05
    game = {"rate_limit": limit, "rate_game": "target", "context": context}
    env = make_dynamic_env("hopper", uncertainty="3d", **game)
    obs_dim = env.observation_space.shape[0]
    assert obs_dim == (14 if context else 11)
    protagonist = MLPPolicy.random(obs_dim, 3, hidden=(16,), seed=1)
    adversary = MLPPolicy.random(obs_dim, 3, hidden=(16,), seed=2)
    result = evaluate_dynamic(
        protagonist, adversary, "hopper", uncertainty="3d", episodes=3, batch_size=2, **game
    )
    assert "rate_game=target" in result.env_id
    box = rrls.get_uncertainty_set("hopper", "3d")
    for row in result.episodes.itertuples(index=False):
        obs, info = env.reset(seed=row.seed)
        here = info["normalized_params"]
        ret, length = 0.0, 0
        while True:
            pair = (protagonist(obs[None])[0], adversary(obs[None])[0])
            obs, reward, terminated, truncated, info = env.step(pair)
            assert np.abs(info["normalized_params"] - here).max() <= limit + 1e-9
            here = info["normalized_params"]
            ret, length = ret + reward, length + 1
            if terminated or truncated:
                break
        assert (row[result.episodes.columns.get_loc("return")], row.length) == (ret, length)
    assert box.dim == 3


@pytest.mark.parametrize(
    "observe, history, omniscient",
    [("vanilla", 1, True), ("vanilla", 1, False), ("stacked", 2, True), ("oracle", 1, True)],
)
def test_dynamic_evaluation_in_the_tc_game_equals_the_plain_loop(observe, history, omniscient):
    radius = 0.05  # raw units: torso mass, thigh mass, friction
    game = {"rate_limit": radius, "observe": observe, "history": history}
    env = make_dynamic_env("hopper", uncertainty="3d", **game)
    (p0, p1), (a0, a1) = env.views
    assert (p1 - p0, a1 - a0) == ({"vanilla": 11, "stacked": 39, "oracle": 14}[observe], 14)
    protagonist = MLPPolicy.random(p1 - p0, 3, hidden=(16,), seed=1)
    adversary = MLPPolicy.random(a1 - a0 + 3 * omniscient, 3, hidden=(16,), seed=2)
    result = evaluate_dynamic(
        protagonist,
        adversary,
        "hopper",
        uncertainty="3d",
        episodes=3,
        batch_size=2,
        omniscient=omniscient,
        **game,
    )
    assert f"rate_limit={radius}, rate_game=tc" in result.env_id
    for row in result.episodes.itertuples(index=False):
        obs, info = env.reset(seed=row.seed)
        ret, length, psi = 0.0, 0, info["psi"]
        while True:
            agent = protagonist(obs[None, p0:p1])[0]
            seen = np.concatenate([obs[a0:a1], agent]) if omniscient else obs[a0:a1]
            obs, reward, terminated, truncated, info = env.step((agent, adversary(seen[None])[0]))
            assert np.abs(info["psi"] - psi).max() <= radius * (1 + 1e-12)  # raw units
            psi = info["psi"]
            ret, length = ret + reward, length + 1
            if terminated or truncated:
                break
        assert (row[result.episodes.columns.get_loc("return")], row.length) == (ret, length)


def _save_pair(tmp_path, obs_dims, game):
    protagonist = MLPPolicy.random(obs_dims[0], 3, hidden=(8,), seed=1)
    adversary = MLPPolicy.random(obs_dims[1], 2, hidden=(8,), seed=2)
    for policy in (protagonist, adversary):
        policy.metadata = {"task": "hopper", "game": "adversarial", "uncertainty": "2d", **game}
        policy.save(tmp_path / ("policy.npz" if policy is protagonist else "adversary.npz"))
    return protagonist, adversary


def test_a_run_of_the_earlier_target_game_is_evaluated_in_its_own_game(tmp_path):
    # what a rate-limited RARL run wrote before TC-RMDP's game: rate_limit alone
    protagonist, adversary = _save_pair(tmp_path, (11, 11), {"rate_limit": 0.02})
    from_run = evaluate_run_dynamic(tmp_path, episodes=2)
    limited = evaluate_dynamic(
        protagonist,
        adversary,
        "hopper",
        uncertainty="2d",
        episodes=2,
        rate_limit=0.02,
        rate_game="target",
    )
    free = evaluate_dynamic(protagonist, adversary, "hopper", uncertainty="2d", episodes=2)
    assert from_run.episodes.equals(limited.episodes)
    assert not limited.episodes["return"].equals(free.episodes["return"])
    assert "rate_limit=0.02, rate_game=target" in from_run.env_id


def test_a_trained_tc_adversary_is_evaluated_in_its_own_game(tmp_path):
    box = rrls.get_uncertainty_set("hopper", "2d")
    game = {"rate_limit": 0.02, "rate_game": "tc", "observe": "oracle", "omniscient": True}
    game["psi_bounds"] = box.as_bounds()  # what RARL records (rrls.wrappers.tc_rmdp.View)
    protagonist, adversary = _save_pair(tmp_path, (13, 16), game)
    from_run = evaluate_run_dynamic(tmp_path, episodes=2)
    direct = evaluate_dynamic(
        protagonist,
        adversary,
        "hopper",
        uncertainty="2d",
        episodes=2,
        rate_limit=0.02,
        observe="oracle",
    )
    assert from_run.episodes.equals(direct.episodes)
    assert "rate_game=tc, observe=oracle, omniscient=True" in from_run.env_id


def test_rate_limit_only_for_the_parameter_game():
    with pytest.raises(ValueError, match="apply to the parameter game"):
        make_dynamic_env("hopper", "nr", rate_limit=0.1)


def test_the_tc_game_has_its_own_oracle():
    with pytest.raises(ValueError, match="use|observe='oracle'"):
        make_dynamic_env("hopper", rate_limit=0.1, context=True)
    with pytest.raises(ValueError, match="is a protagonist of the TC-RMDP game"):
        make_dynamic_env("hopper", observe="stacked")
