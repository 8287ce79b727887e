"""The paper's baselines as the RRLS authors ran them: each choice checked against the source it
cites (RARL's update schedule, M2TD3's warm-up, NR-MDP's details, the paper's mesh)."""

from __future__ import annotations

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from rrls.agents import TrainConfig, algorithm, hyperparameters  # noqa: E402
from rrls.agents.streams import RunSeeds  # noqa: E402


def _rarl(schedule: str):
    config = TrainConfig(
        algo="rarl",
        task="invertedpendulum",
        hyper={"schedule": schedule, "phase_steps": 5, "hidden": (8,), "batch_size": 4},
    )
    hyper = hyperparameters(config)
    env = algorithm("rarl").make_env(config.task, config.uncertainty, hyper)
    learner = algorithm("rarl").Learner(env, hyper, [RunSeeds(0)], torch.device("cpu"))
    obs = np.zeros((1, env.observation_space.shape[0]), np.float32)
    rng = np.random.default_rng(0)
    for _ in range(8):  # a few transitions in both buffers
        nxt = rng.normal(size=obs.shape).astype(np.float32)
        learner.observe(obs, learner.act(obs), np.ones(1), nxt, np.zeros(1, bool), [{}])
        obs = nxt
    return learner, hyper


def _critics(learner):
    return [
        torch.cat([p.detach().flatten().clone() for p in player.critic.parameters()])
        for player in learner.players
    ]


def test_rarl_updates_both_players_every_step_by_default_as_the_rrls_authors_trainer():
    # SuReLI/TCRMDP src/td3/trainer.py:418-431: agent.update then adversary.update, each step
    learner, hyper = _rarl("simultaneous")
    assert hyperparameters(TrainConfig(algo="rarl", task="hopper")).schedule == "simultaneous"
    for step in (hyper.learning_starts + 1, hyper.learning_starts + 7):
        before = _critics(learner)
        losses = learner.update(step)
        after = _critics(learner)
        assert all(not torch.equal(b, a) for b, a in zip(before, after))
        assert {"protagonist_critic_loss", "adversary_critic_loss"} <= set(losses)


def test_rarls_alternating_phases_stay_available_by_name():
    # Pinto et al. 2017, Algorithm 1: one player learns per phase of phase_steps env steps
    learner, hyper = _rarl("alternating")
    start = hyper.learning_starts
    for step, learning in ((start + 1, 0), (start + 5, 0), (start + 6, 1), (start + 11, 0)):
        before = _critics(learner)
        learner.update(step)
        after = _critics(learner)
        changed = [not torch.equal(b, a) for b, a in zip(before, after)]
        assert changed == [i == learning for i in (0, 1)], step
    with pytest.raises(ValueError, match="schedule must be one of simultaneous, alternating"):
        _rarl("phases")


def test_m2td3_warms_up_for_its_authors_100k_random_steps_in_every_paper_preset():
    # SuReLI/TCRMDP src/main_m2td3.py:16 (start_steps: int = 1e5), akimotolab/M2TD3's configs
    from rrls.benchmark.grid import make_spec

    assert hyperparameters(TrainConfig(algo="m2td3", task="hopper")).learning_starts == 100_000
    assert hyperparameters(TrainConfig(algo="td3", task="hopper")).learning_starts == 25_000
    for preset in ("hopper-200k", "hopper", "halfcheetah", "paper"):
        spec = make_spec(preset)
        assert spec.hyperparameters("m2td3")["learning_starts"] == 100_000, preset
        assert spec.hyperparameters("td3")["learning_starts"] == 25_000, preset
    # a reduced budget still learns: one warm-up for all, at most a fifth of the steps
    short = make_spec("hopper", steps=50_000)
    assert {short.hyperparameters(a)["learning_starts"] for a in short.algos} == {10_000}


@pytest.mark.parametrize("preset", ["hopper-200k", "hopper", "halfcheetah", "paper"])
def test_presets_that_claim_the_papers_mesh_evaluate_on_np_arange(preset):
    # the original code's mesh: np.arange(low, high, (high - low) / n), upper bound excluded
    from rrls.benchmark.grid import make_spec
    from rrls.envs import get_uncertainty_set

    spec = make_spec(preset, tasks="halfcheetah")
    plan = spec.protocol.plan("halfcheetah")
    box = get_uncertainty_set("halfcheetah", spec.uncertainty)
    axes = [np.arange(lo, hi, (hi - lo) / spec.mesh) for lo, hi in zip(box.low, box.high)]
    expected = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, len(axes))
    assert plan.settings["endpoint"] is False and len(plan.points) == spec.mesh**3
    np.testing.assert_allclose(np.unique(plan.points, axis=0), np.unique(expected, axis=0))
    assert (plan.points < np.asarray(box.high)).all()
