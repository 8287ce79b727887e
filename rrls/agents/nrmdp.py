"""NR-MDP (Tessler et al. 2019, "Action Robust Reinforcement Learning"), on the TD3 core.

A protagonist and an adversary on ``ProbabilisticActionRobust``: the executed action is
``(1 - alpha) * a + alpha * a_adv`` (NR-MDP, alpha 0.1 by default) or, with ``mode="pr"``, the
adversary's action with probability alpha (PR-MDP). Both are TD3 learners updated at every step
(Tessler et al. train both players simultaneously); the adversary maximises ``-reward``.

Difference from Tessler et al.: each player has its own twin critic over its own action (the
two-learner form RARL uses), not one critic over the mixed action. Same game, same objectives.
"""

from __future__ import annotations

from pathlib import Path

from rrls.agents.common import TrainConfig, make_env
from rrls.agents.rarl import train_two_player

ALPHA = 0.1


def train(
    config: TrainConfig, resume: bool = False, alpha: float = ALPHA, mode: str = "nr"
) -> Path:
    """Train NR-MDP (``mode="nr"``) or PR-MDP (``mode="pr"``) with mixing ``alpha``."""
    from rrls.wrappers import ProbabilisticActionRobust

    env = ProbabilisticActionRobust(make_env(config.task), alpha=alpha, mode=mode)
    game = {"game": mode, "alpha": alpha}
    return train_two_player(config, env, lambda step: (True, True), resume, game)
