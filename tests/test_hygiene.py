"""Wrapper input hygiene: empty sets, NaN/inf actions, leftover chunk files."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import rrls
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
    kw = dict(mesh=2, episodes=1, workers=1, out_dir=tmp_path, max_episode_steps=20)
    first = evaluate(still, "invertedpendulum", "1d", **kw)
    chunks = tmp_path / "chunks"
    leftover = chunks / ".000000.npz.k1ll3d.tmp"
    leftover.write_bytes(b"half a chunk")
    (chunks / "000000.npz").unlink()  # as if killed while writing it
    again = evaluate(still, "invertedpendulum", "1d", **kw)
    assert not leftover.exists()
    assert [p.name for p in chunks.iterdir()] == ["000000.npz"]
    assert again.episodes.equals(first.episodes)


def test_the_package_is_typed_and_its_public_names_are_listed_once():
    import collections
    from pathlib import Path

    assert (Path(rrls.__file__).parent / "py.typed").is_file()  # PEP 561: type hints ship
    twice = [n for n, k in collections.Counter(rrls.__all__).items() if k > 1]
    assert twice == [] and all(hasattr(rrls, n) for n in rrls.__all__)
