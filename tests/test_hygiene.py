"""Wrapper input hygiene: empty sets, NaN/inf actions, leftover chunk files; the rate limit."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import rrls  # noqa: F401
from rrls.envs import HopperParamsBound, RobustHopper
from rrls.evaluation import evaluate
from rrls.uncertainty import UncertaintySet
from rrls.wrappers import DomainRandomization, DynamicAdversarial, ProbabilisticActionRobust


@pytest.mark.parametrize("wrapper", [DomainRandomization, DynamicAdversarial])
@pytest.mark.parametrize("empty", [{}, UncertaintySet((), [], [])])
def test_empty_sets_are_refused(wrapper, empty):
    with pytest.raises(ValueError, match="at least one parameter.*valid names: .*torsomass"):
        wrapper(RobustHopper(), empty)


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_non_finite_actions_name_the_step(bad):
    action = np.zeros(3)
    envs = {
        "make": gym.make("rrls/robust-hopper-v0"),
        "dr": DomainRandomization(RobustHopper(), HopperParamsBound.TWO_DIM.value),
    }
    for env in envs.values():
        env.reset(seed=0)
        env.step(action)
        env.step(action)
        with pytest.raises(ValueError, match=r"^action at step 3 of the episode is not finite"):
            env.step(np.array([0.0, bad, 0.0]))
        env.reset(seed=1)  # the count restarts with each episode
        with pytest.raises(ValueError, match="at step 1 "):
            env.step(np.array([bad, 0.0, 0.0]))
    game = DynamicAdversarial(RobustHopper(), HopperParamsBound.TWO_DIM.value)
    game.reset(seed=0)
    game.step((action, np.zeros(2)))
    with pytest.raises(ValueError, match="adversary action at step 2 .*must be finite"):
        game.step((action, np.array([bad, 0.0])))
    pr = ProbabilisticActionRobust(RobustHopper())
    pr.reset(seed=0)
    with pytest.raises(ValueError, match="agent action at step 1 "):
        pr.step((np.array([bad, 0.0, 0.0]), action))


def test_error_is_one_line():
    env = gym.make("rrls/robust-hopper-v0")
    env.reset(seed=0)
    with pytest.raises(ValueError) as err:
        env.step(np.full(3, np.nan))
    assert "\n" not in str(err.value)


def test_leftover_temporary_chunks_are_removed_at_resume(tmp_path):
    still = lambda obs: np.zeros((len(obs), 1))  # noqa: E731
    kw = dict(nb_mesh_dim=2, episodes=1, workers=1, out_dir=tmp_path, max_episode_steps=20)
    first = evaluate(still, "invertedpendulum", "1d", **kw)
    chunks = tmp_path / "chunks"
    leftover = chunks / ".000000.npz.k1ll3d.tmp"
    leftover.write_bytes(b"half a chunk")
    (chunks / "000000.npz").unlink()  # as if killed while writing it
    again = evaluate(still, "invertedpendulum", "1d", **kw)
    assert not leftover.exists()
    assert [p.name for p in chunks.iterdir()] == ["000000.npz"]
    assert again.episodes.equals(first.episodes)


# -- the rate-limited adversary (TC-RMDP) ------------------------------------------------------
@pytest.mark.parametrize("limit", [0.0, 0.05, 0.3])
def test_rate_limit_holds_at_every_step(limit):
    box = UncertaintySet.from_bounds(HopperParamsBound.THREE_DIM.value)
    game = DynamicAdversarial(RobustHopper(), box, rate_limit=limit)
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
    limited = DynamicAdversarial(RobustHopper(), box, rate_limit=2.0)
    rng = np.random.default_rng(1)
    free.reset(seed=3)
    limited.reset(seed=3)
    for _ in range(50):
        pair = (rng.uniform(-1, 1, 3), rng.uniform(-1, 1, 2))
        a, b = free.step(pair), limited.step(pair)
        assert np.array_equal(a[0], b[0]) and a[1] == b[1]
        assert free.get_params() == limited.get_params()


@pytest.mark.parametrize("bad", [-0.1, np.nan, np.inf, "fast", True])
def test_bad_rate_limits_are_refused(bad):
    with pytest.raises(ValueError, match="rate_limit must be a finite number >= 0"):
        DynamicAdversarial(RobustHopper(), HopperParamsBound.ONE_DIM.value, rate_limit=bad)
