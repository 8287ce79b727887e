"""Training's periodic evaluation plans its protocols once and keeps its envs, yet gives the
numbers the public ``evaluate`` gives (the same plan, seeds and engine)."""

from __future__ import annotations

import pytest

pytest.importorskip("torch")

from rrls.agents import TrainConfig
from rrls.agents.run import PeriodicEvaluation
from rrls.evaluation import MLPPolicy, evaluate


def test_periodic_evaluation_equals_evaluate_and_reuses_its_plan(tmp_path):
    config = TrainConfig(
        algo="td3", task="invertedpendulum", steps=10, out=str(tmp_path), eval_mesh=2
    )
    periodic = PeriodicEvaluation(config)
    for seed in (1, 2):  # two policies through the same planned evaluators
        policy = MLPPolicy.random(obs_dim=4, act_dim=1, hidden=(8,), seed=seed)
        scores = periodic(policy)
        common = {"seed": PeriodicEvaluation.SEED, "workers": 1, "progress": False}
        nominal = evaluate(policy, "invertedpendulum", "nominal", episodes=5, **common)
        mesh = evaluate(policy, "invertedpendulum", "2d", mesh=2, episodes=1, **common)
        assert scores == {
            "eval/nominal_return": nominal.average_case,
            "eval/worst_case": mesh.worst_case,
            "eval/average_case": mesh.average_case,
        }
    planned = periodic._evaluators
    periodic(policy)
    assert periodic._evaluators is planned  # planned once
    periodic.close()
