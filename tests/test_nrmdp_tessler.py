"""NR-MDP's opt-in details of Tessler's code: pooled observation standardisation, critic L2."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import stopping_at

torch = pytest.importorskip("torch")

from rrls.agents.algos import nrmdp  # noqa: E402
from rrls.agents.run import read_checkpoint  # noqa: E402
from rrls.agents.streams import RunSeeds  # noqa: E402
from rrls.cli import main  # noqa: E402
from rrls.rundir import CHECKPOINT  # noqa: E402

#: the long end-to-end tier (.ci/run runs it after the default suite)
pytestmark = pytest.mark.e2e

TESSLER = ["--normalize-obs", "--critic-weight-decay", "1e-2"]


def tesslers_running_mean_std(states: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """His ``RunningMeanStd`` (``utils.py``) fed as ``store_transition`` feeds it: one 1-D
    state per ``update``, moments along axis 0 of that state."""
    mean, var, count = np.zeros(states.shape[1]), np.ones(states.shape[1]), 1e-4
    for x in states:
        batch_mean, batch_var, batch_count = np.mean(x, axis=0), np.var(x, axis=0), x.shape[0]
        delta, total = batch_mean - mean, count + batch_count
        m2 = var * count + batch_var * batch_count + np.square(delta) * count * batch_count / total
        mean, var, count = mean + delta * batch_count / total, m2 / total, total
    return mean, var


def test_pooled_stats_are_tesslers_running_mean_std_one_state_at_a_time():
    rng = np.random.default_rng(0)
    scales = np.array([0.1, 1.0, 10.0, 3.0, 0.5])  # features of different scales: pooled anyway
    states = [rng.normal(2.0, scales, (300, 5)).astype(np.float32) for _ in range(2)]
    stats = nrmdp.PooledStats(2, "cpu")
    for t in range(300):
        stats.update(np.stack([states[0][t], states[1][t]]))
    for k in range(2):
        mean, var = tesslers_running_mean_std(states[k].astype(np.float64))
        assert np.allclose(mean, stats.mean[k], rtol=1e-12) and np.ptp(mean) == 0  # one value
        assert np.allclose(var, stats.var[k], rtol=1e-9)
    assert stats.var[0] != stats.var[1]  # each run its own


def _learner(**options):
    config = nrmdp.Config(hidden=(16, 16), batch_size=8, **options)
    env = nrmdp.make_env("hopper", None, config)
    return nrmdp.Learner(env, config, [RunSeeds(0), RunSeeds(1)], "cpu"), env


def test_exported_policies_fold_the_standardisation_into_their_first_layer():
    learner, env = _learner(normalize_obs=True)
    rng = np.random.default_rng(1)
    for _ in range(50):
        learner.stats.update(rng.normal(0.5, 3.0, (2, env.observation_space.shape[0])))
    obs = rng.normal(0.5, 3.0, (2, env.observation_space.shape[0])).astype(np.float32)
    seen = learner.stats.normalize(obs)
    assert learner.stats.std32[0, 0] > 2.0  # the stats moved: folding is not the identity
    for k in range(2):
        exported = learner.export(k)
        for name, module in (("policy", learner.agent.actor), ("adversary", learner.opponent)):
            with torch.no_grad():
                x = torch.from_numpy(seen[k : k + 1]).expand(2, 1, -1)
                trained = module(x)[k, 0].numpy()
            assert np.allclose(exported[name](obs[k : k + 1])[0], trained, atol=1e-5), name


def test_options_are_off_by_default_and_the_critic_decays_when_asked():
    plain, _ = _learner()
    assert plain.stats is None
    assert all(g["weight_decay"] == 0 for g in plain.agent.critic_opt.param_groups)
    learner, _ = _learner(critic_weight_decay=1e-2)
    assert all(g["weight_decay"] == 1e-2 for g in learner.agent.critic_opt.param_groups)
    assert all(g["weight_decay"] == 0 for g in learner.agent.actor_opt.param_groups)
    with pytest.raises(ValueError, match="critic_weight_decay"):
        nrmdp.Config(critic_weight_decay=-1.0)


def _train(out, steps=400, extra=()):
    args = ["train", "--algo", "nrmdp", "--task", "invertedpendulum", "--steps", str(steps)]
    args += ["--learning-starts", "100", "--eval-every", "200", "--seed", "1", "--out", str(out)]
    args += ["--checkpoint-every", "50", "--hidden", "16", "16", "--batch-size", "32"]
    return main([*args, "--ratio", "2", *TESSLER, *extra])


def test_tesslers_options_train_and_resume_bit_identical(tmp_path):
    assert _train(tmp_path / "whole") == 0
    with stopping_at(220):
        assert _train(tmp_path / "cut") == 3
    assert _train(tmp_path / "cut", extra=["--resume"]) == 0
    whole, cut = (read_checkpoint(tmp_path / d / CHECKPOINT) for d in ("whole", "cut"))
    stats = whole["learner"]["obs_stats"]
    assert float(stats["count"][0]) == pytest.approx(400 * 4, abs=1e-3)  # 4 features a state
    for name in ("mean", "var", "count"):
        assert torch.equal(stats[name], cut["learner"]["obs_stats"][name]), name
    critic = "layers.0.weight"
    assert torch.equal(
        whole["learner"]["agent"]["critic"][critic], cut["learner"]["agent"]["critic"][critic]
    )
    a, b = (np.load(tmp_path / d / "policy.npz") for d in ("whole", "cut"))
    assert all(np.array_equal(a[k], b[k]) for k in a.files if k != "header")
