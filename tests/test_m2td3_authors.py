"""M2TD3's opt-in details of its authors' trainer: unclipped exploration, one start state."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import stopping_at

torch = pytest.importorskip("torch")

from rrls.agents.algos import m2td3  # noqa: E402
from rrls.agents.run import read_checkpoint  # noqa: E402
from rrls.agents.streams import RunSeeds  # noqa: E402
from rrls.cli import main  # noqa: E402
from rrls.rundir import CHECKPOINT  # noqa: E402

#: the long end-to-end tier (.ci/run runs it after the default suite)
pytestmark = pytest.mark.e2e

AUTHORS = ["--no-clip-exploration", "--same-start"]


def _train(out, extra=(), steps=300):
    args = ["train", "--algo", "m2td3", "--task", "invertedpendulum", "--uncertainty", "1d"]
    args += ["--steps", str(steps), "--learning-starts", "100", "--eval-every", "0"]
    args += ["--seed", "1", "--out", str(out), "--checkpoint-every", "50"]
    args += ["--hidden", "16", "16", "--batch-size", "32", "--exploration-noise", "2.0"]
    return main([*args, *extra])


def _rows(run_dir) -> dict[str, np.ndarray]:
    """The run's replay, by field (InvertedPendulum: 4 observations, 1 action, ω of the 1D set)."""
    table = read_checkpoint(run_dir / CHECKPOINT)["learner"]["buffer"]["table"][0].numpy()
    sizes = {"obs": 4, "action": 1, "reward": 1, "next_obs": 4, "terminated": 1, "omega": 1}
    edges = np.cumsum([0, *sizes.values()])
    return {name: table[:, a:b] for name, a, b in zip(sizes, edges[:-1], edges[1:])}


def test_unclipped_exploration_is_the_same_draw_without_the_clip():
    config = dict(hidden=(16, 16), exploration_noise=2.0)
    env = m2td3.make_env("invertedpendulum", "1d", m2td3.Config(**config))
    obs = np.zeros((2, 4), np.float32)
    seeds = [RunSeeds(0), RunSeeds(1)]
    clipped = m2td3.Learner(env, m2td3.Config(**config), seeds, "cpu").act(obs)
    raw = m2td3.Learner(env, m2td3.Config(**config, clip_exploration=False), seeds, "cpu")
    raw = np.array(raw.act(obs))
    low, high = env.action_space.low, env.action_space.high
    assert np.array_equal(np.clip(raw, low, high), np.array(clipped))
    assert ((raw < low) | (raw > high)).any()  # σ = 2 half-ranges: some leave the box


def test_authors_trainer_stores_unclipped_actions_and_starts_every_episode_alike(tmp_path):
    assert _train(tmp_path / "authors", AUTHORS) == 0
    assert _train(tmp_path / "rrls") == 0
    for name, same in (("authors", True), ("rrls", False)):
        rows = _rows(tmp_path / name)
        learned = rows["action"][100:]  # after the uniform warm-up
        outside = (np.abs(learned) > 3.0).any()  # InvertedPendulum's box is [-3, 3]
        assert outside == same, name
        begins = np.flatnonzero((rows["obs"][1:] != rows["next_obs"][:-1]).any(1)) + 1
        starts = rows["obs"][np.r_[0, begins]]
        assert len(starts) >= 5, name
        assert (starts == starts[0]).all() == same, name


def test_authors_options_resume_bit_identical(tmp_path):
    assert _train(tmp_path / "whole", AUTHORS, steps=400) == 0
    with stopping_at(220):
        assert _train(tmp_path / "cut", AUTHORS, steps=400) == 3
    assert _train(tmp_path / "cut", [*AUTHORS, "--resume"], steps=400) == 0
    a, b = (read_checkpoint(tmp_path / d / CHECKPOINT)["learner"] for d in ("whole", "cut"))
    assert torch.equal(a["buffer"]["table"], b["buffer"]["table"])
    assert torch.equal(
        a["agent"]["actor"]["layers.0.weight"], b["agent"]["actor"]["layers.0.weight"]
    )
