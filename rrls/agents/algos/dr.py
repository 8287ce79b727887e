"""Domain Randomization (Tobin et al. 2017, "Domain Randomization for Transferring Deep Neural
Networks from Simulation to the Real World"; https://arxiv.org/abs/1703.06907): TD3 on
environments whose parameters are drawn uniformly from the uncertainty set at every episode
(``rrls.wrappers.DomainRandomization``).

The learner is TD3's, unchanged; only the environment differs. The draws come from the
environment's own seeded generator (the run's ``"env"`` stream), so they are part of the
checkpoint.
"""

from __future__ import annotations

from typing import Any

from rrls.agents.algos.td3 import Config, Learner
from rrls.agents.envs import task_env


def make_env(task: str, uncertainty: Any, config: Config, paper: bool = False) -> Any:
    """The task whose parameters (or forces, for ``rarl``) are redrawn at every reset."""
    from rrls.wrappers import DomainRandomization

    env, box = task_env(task, uncertainty, paper)
    return DomainRandomization(env, box)


__all__ = ["Config", "Learner", "make_env"]
