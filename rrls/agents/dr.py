"""Domain Randomization (Tobin et al. 2017): TD3 on environments whose parameters are drawn
uniformly from the uncertainty set at every episode (``rrls.wrappers.DomainRandomization``).

The draws come from the environment's own seeded generator, so they are part of the checkpoint.
"""

from __future__ import annotations

from pathlib import Path

from rrls.agents.common import TrainConfig, make_env
from rrls.agents.td3 import train_single_agent
from rrls.envs import get_uncertainty_set
from rrls.wrappers import DomainRandomization


def train(config: TrainConfig, resume: bool = False) -> Path:
    """Train TD3 under domain randomisation over ``config.uncertainty``."""
    box = get_uncertainty_set(config.task, config.uncertainty)
    kind = "force" if config.uncertainty == "rarl" else "robust"
    env = DomainRandomization(make_env(config.task, kind), box)
    return train_single_agent(config, env, resume)
