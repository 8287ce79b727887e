"""SAC's initial temperature is CleanRL's: autotuned runs start at log α = 0 (α₀ = 1,
``cleanrl/sac_continuous_action.py:205``, ``log_alpha = torch.zeros(1)``); the configured α
(0.2, ``:63``) is used only without autotuning (``:209``, ``alpha = args.alpha``)."""

from __future__ import annotations

import math

import numpy as np
import pytest

torch = pytest.importorskip("torch")


class _Spaces:
    def __init__(self, obs_dim: int, act_dim: int) -> None:
        import gymnasium as gym

        self.observation_space = gym.spaces.Box(-np.inf, np.inf, (obs_dim,))
        self.action_space = gym.spaces.Box(-1, 1, (act_dim,), np.float32)


@pytest.mark.parametrize("algo", ["sac", "sacdr"])
def test_autotuned_temperature_starts_at_one_and_a_fixed_one_at_entropy_coef(algo):
    from rrls.agents import algorithm
    from rrls.agents.streams import RunSeeds

    module = algorithm(algo)
    seeds = [RunSeeds(0), RunSeeds(1)]
    tuned = module.Learner(_Spaces(5, 2), module.Config(hidden=(8,)), seeds, "cpu")
    assert tuned.log_alpha.detach().tolist() == [0.0, 0.0]
    # entropy_coef is the fixed temperature, not the autotuned start
    tuned = module.Learner(
        _Spaces(5, 2), module.Config(hidden=(8,), entropy_coef=0.05), seeds, "cpu"
    )
    assert tuned.log_alpha.detach().tolist() == [0.0, 0.0]
    fixed = module.Learner(_Spaces(5, 2), module.Config(hidden=(8,), autotune=False), seeds, "cpu")
    assert fixed.log_alpha.detach().tolist() == pytest.approx([math.log(0.2)] * 2)
    assert module.Config().entropy_coef == 0.2 and module.Config().autotune is True
