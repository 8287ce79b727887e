"""The evaluation engine: every row equals the plain one-episode loop, whatever workers/batch."""

from __future__ import annotations

import json

import gymnasium as gym
import numpy as np
import pandas as pd
import pytest
from conftest import TASK_KEYS

import rrls  # noqa: F401
from rrls.evaluation import (
    BatchInvariant,
    EvaluationResult,
    MLPPolicy,
    PolicyError,
    evaluate,
    load_policy,
)
from rrls.evaluation.runner import episode_seeds
from rrls.uncertainty import UncertaintySet


def _policy(task: str, seed: int = 3) -> MLPPolicy:
    env = gym.make(f"rrls/robust-{task}-v0")
    return MLPPolicy.random(
        env.observation_space.shape[0], env.action_space.shape[0], hidden=(32, 32), seed=seed
    )


def plain_loop(env_id: str, policy, params: dict, seed: int, max_steps: int) -> tuple[float, int]:
    """The issue's reference: make, set_params, reset(seed), policy(obs[None])[0] until done."""
    env = gym.make(env_id, max_episode_steps=max_steps)
    env.set_params(**params)
    obs, _ = env.reset(seed=seed)
    ret, length = 0.0, 0
    while True:
        obs, reward, terminated, truncated, _ = env.step(policy(obs[None])[0])
        ret += reward
        length += 1
        if terminated or truncated:
            return ret, length


# Long-lived tasks get shorter episodes so the whole check stays fast.
STEPS = {"ant": 150, "halfcheetah": 300, "humanoidstandup": 100}


@pytest.mark.parametrize("task", TASK_KEYS)
def test_rows_equal_the_plain_loop(task):
    policy = _policy(task)
    steps = STEPS.get(task, 1000)
    result = evaluate(
        policy, task, "2d", nb_mesh_dim=2, episodes=2, seed=7, workers=1, max_episode_steps=steps
    )
    assert len(result.episodes) == 8
    for row in result.episodes.itertuples(index=False):
        params = {n: getattr(row, n) for n in result.param_names}
        ret, length = plain_loop(f"rrls/robust-{task}-v0", policy, params, row.seed, steps)
        assert (row.length, row[result.episodes.columns.get_loc("return")]) == (length, ret)


@pytest.mark.parametrize("uncertainty", ["rarl", "nominal"])
def test_force_set_and_nominal_equal_the_plain_loop(uncertainty):
    policy = _policy("hopper")
    result = evaluate(policy, "hopper", uncertainty, nb_mesh_dim=2, episodes=1, workers=1)
    family = "force" if uncertainty == "rarl" else "robust"
    for row in result.episodes.itertuples(index=False):
        params = {n: getattr(row, n) for n in result.param_names}
        ret, length = plain_loop(f"rrls/{family}-hopper-v0", policy, params, row.seed, 1000)
        assert row.length == length
        assert row[result.episodes.columns.get_loc("return")] == ret
    if uncertainty == "nominal":
        assert len(result.episodes) == 1 and result.param_names == []


def test_results_do_not_depend_on_workers_or_batch_size():
    policy = _policy("walker")
    runs = [
        evaluate(
            policy, "walker", "3d", nb_mesh_dim=2, episodes=3, seed=1, workers=w, batch_size=b
        ).episodes
        for w, b in [(1, 1), (1, 5), (1, 64), (2, 3), (2, 64)]
    ]
    for other in runs[1:]:
        pd.testing.assert_frame_equal(runs[0], other, check_exact=True)


def test_table_columns_seeds_and_scores():
    policy = _policy("invertedpendulum")
    result = evaluate(
        policy, "invertedpendulum", "2d", nb_mesh_dim=3, episodes=4, seed=5, workers=1
    )
    frame = result.episodes
    assert list(frame.columns) == [
        "point",
        "polemass",
        "cartmass",
        "episode",
        "seed",
        "return",
        "length",
        "terminated",
        "diverged",
    ]
    assert len(frame) == 9 * 4 and frame["seed"].nunique() == 36
    np.testing.assert_array_equal(frame["seed"], episode_seeds(5, 9, 4).reshape(-1))
    assert not np.array_equal(episode_seeds(5, 9, 4), episode_seeds(6, 9, 4))
    # seeds depend on (point, episode) only, not on how many points there are
    np.testing.assert_array_equal(episode_seeds(5, 9, 4)[:4], episode_seeds(5, 4, 4))
    per_point = frame.groupby("point")["return"].mean()
    assert result.worst_case == per_point.min()
    assert result.average_case == pytest.approx(per_point.mean(), rel=1e-12)
    worst = frame[frame["point"] == per_point.idxmin()].iloc[0]
    assert result.worst_point == {"polemass": worst["polemass"], "cartmass": worst["cartmass"]}
    # mesh includes both bounds by default
    assert sorted(frame["polemass"].unique()) == [1.0, 16.0, 31.0]


def test_same_seed_same_numbers_other_seed_other_numbers():
    policy = _policy("hopper")
    a = evaluate(policy, "hopper", "1d", nb_mesh_dim=2, episodes=2, seed=0, workers=1)
    b = evaluate(policy, "hopper", "1d", nb_mesh_dim=2, episodes=2, seed=0, workers=2)
    c = evaluate(policy, "hopper", "1d", nb_mesh_dim=2, episodes=2, seed=1, workers=1)
    pd.testing.assert_frame_equal(a.episodes, b.episodes)
    assert not np.array_equal(a.episodes["return"], c.episodes["return"])


class FlakyPolicy:
    """A policy that raises after ``fail_after`` calls (an interruption), else ``inner``."""

    def __init__(self, inner, fail_after: int | None = None) -> None:
        self.inner, self.fail_after, self.calls, self.rows = inner, fail_after, 0, 0

    def __call__(self, obs):
        self.calls += 1
        self.rows += len(obs)
        if self.fail_after is not None and self.calls > self.fail_after:
            raise KeyboardInterrupt
        return self.inner(obs)


def test_interrupted_evaluation_resumes_to_the_same_result(tmp_path):
    inner = _policy("invertedpendulum")
    kwargs = dict(
        task="invertedpendulum",
        uncertainty="2d",
        nb_mesh_dim=4,
        episodes=10,
        seed=3,
        workers=1,
        batch_size=4,
    )  # 160 episodes = 4 chunks of 50, 4 lanes
    counting = FlakyPolicy(inner)
    full = evaluate(counting, **kwargs)

    out = tmp_path / "run"
    with pytest.raises(KeyboardInterrupt):  # killed halfway through
        evaluate(FlakyPolicy(inner, fail_after=counting.calls // 2), out_dir=out, **kwargs)
    saved = sorted((out / "chunks").glob("*.npz"))
    assert 0 < len(saved) < 4 and not (out / "summary.json").exists()

    resumed_policy = FlakyPolicy(inner)
    resumed = evaluate(resumed_policy, out_dir=out, **kwargs)
    pd.testing.assert_frame_equal(full.episodes, resumed.episodes, check_exact=True)
    assert resumed_policy.rows < 0.9 * counting.rows  # the saved chunks were not run again

    summary = json.loads((out / "summary.json").read_text())
    assert summary["worst_case"] == full.worst_case
    assert {"task", "uncertainty", "mesh", "episodes", "seed", "versions"} <= set(summary)
    loaded = EvaluationResult.load(out)
    pd.testing.assert_frame_equal(loaded.episodes, full.episodes, check_dtype=False)
    assert loaded.worst_case == full.worst_case and loaded.average_case == full.average_case


def test_resume_refuses_other_arguments(tmp_path):
    policy = _policy("invertedpendulum")
    evaluate(
        policy, "invertedpendulum", "1d", nb_mesh_dim=2, episodes=1, out_dir=tmp_path, workers=1
    )
    with pytest.raises(ValueError, match="different arguments.*episodes"):
        evaluate(
            policy, "invertedpendulum", "1d", nb_mesh_dim=2, episodes=2, out_dir=tmp_path, workers=1
        )
    with pytest.raises(ValueError, match="policy_fingerprint"):
        evaluate(
            _policy("invertedpendulum", seed=9),
            "invertedpendulum",
            "1d",
            nb_mesh_dim=2,
            episodes=1,
            out_dir=tmp_path,
            workers=1,
        )


@pytest.mark.parametrize("workers", [1, 2])
def test_nan_actions_name_the_point_and_step(workers):
    inner = _policy("hopper")

    def nan_late(obs):
        actions = inner(obs)
        actions[np.abs(obs[:, 0] - 1.25) > 0.05] = np.nan  # once the torso has moved a bit
        return actions

    with pytest.raises(
        PolicyError, match=r"non-finite.*mesh point \d+ \{'worldfriction'.*step \d+"
    ):
        evaluate(nan_late, "hopper", "1d", nb_mesh_dim=2, episodes=1, workers=workers)


def test_wrong_action_shape_is_refused_before_rollouts():
    with pytest.raises(PolicyError, match=r"expected \(2, 3\)"):
        evaluate(lambda obs: np.zeros((len(obs), 2)), "hopper", "1d", nb_mesh_dim=2, workers=1)

    calls = []

    def shape_changes(obs):  # right at first, then wrong mid-evaluation
        calls.append(len(obs))
        return np.zeros((len(obs), 3 if len(calls) < 50 else 4))

    with pytest.raises(PolicyError, match=r"shape .*mesh point .*step"):
        evaluate(shape_changes, "hopper", "1d", nb_mesh_dim=2, episodes=1, workers=1)


def test_divergence_is_recorded_not_raised():
    huge = UncertaintySet(("torsoforce_x",), [0.0], [1e12], [0.0], "hopper/huge-force")
    zero = lambda obs: np.zeros((len(obs), 3))  # noqa: E731
    with pytest.warns(UserWarning, match="diverged"):
        result = evaluate(zero, "hopper", huge, nb_mesh_dim=2, episodes=1, workers=1)
    frame = result.episodes
    assert frame["diverged"].tolist() == [False, True]
    assert np.isfinite(frame["return"]).all()
    assert result.summary()["diverged"] == 1


def test_non_batch_invariant_policy_warns():
    rng = np.random.default_rng(0)
    w = rng.normal(size=(11, 3)).astype(np.float32)

    def leaky(obs):  # its output depends on the batch: a row-order sum over the batch
        return np.tanh(obs.astype(np.float32) @ w) + 1e-7 * len(obs)

    with pytest.warns(UserWarning, match="BatchInvariant"):
        evaluate(leaky, "hopper", "1d", nb_mesh_dim=2, episodes=1, workers=1)
    wrapped = BatchInvariant(leaky)
    np.testing.assert_array_equal(wrapped(np.ones((70, 11)))[3], wrapped(np.ones((1, 11)))[0])


def test_mlp_policy_file_round_trip_and_refusals(tmp_path):
    policy = MLPPolicy.random(11, 3, hidden=(16,), seed=2)
    path = policy.save(tmp_path / "policy.npz")
    loaded = load_policy(path)
    obs = np.random.default_rng(0).normal(size=(5, 11))
    np.testing.assert_array_equal(policy(obs), loaded(obs))
    np.savez(tmp_path / "other.npz", w=np.zeros(3))
    with pytest.raises(ValueError, match="not an rrls MLP policy"):
        load_policy(tmp_path / "other.npz")
    with pytest.raises(FileNotFoundError):
        load_policy(tmp_path / "missing.npz")
    with pytest.raises(ValueError, match="expected observations of shape"):
        policy(np.zeros((2, 7)))


def test_mlp_policy_is_batch_invariant_at_large_batches():
    policy = MLPPolicy.random(17, 6, seed=0)  # 256-256, the benchmark's size
    obs = np.random.default_rng(4).normal(size=(1000, 17))
    batch = policy(obs)
    for i in (0, 63, 64, 500, 999):
        np.testing.assert_array_equal(batch[i], policy(obs[i : i + 1])[0])


def test_bad_arguments():
    policy = _policy("hopper")
    with pytest.raises(ValueError, match="valid tasks"):
        evaluate(policy, "cartpole", "1d")
    with pytest.raises(ValueError, match="valid: 1d, 2d, rarl"):
        evaluate(policy, "invertedpendulum", "3d")
    with pytest.raises(ValueError, match="episodes"):
        evaluate(policy, "hopper", "1d", episodes=0)
