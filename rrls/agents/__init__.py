"""Baselines on one TD3 core (needs the ``train`` extra: torch, tensorboard).

``train(config)`` runs the one collection loop (``rrls.agents.loop``) with the algorithm's
learner: ``td3``, ``dr``, ``rarl``, ``nrmdp``, ``m2td3`` — one file each, holding its paper
reference, its hyper-parameters (``Config``, the paper's values) and its learner.
"""

from __future__ import annotations

from rrls.agents.common import ALGOS, Interrupted, TrainConfig, benchmark_set
from rrls.agents.loop import algorithm, hyperparameters, train, train_group

__all__ = [
    "ALGOS",
    "Interrupted",
    "TrainConfig",
    "algorithm",
    "benchmark_set",
    "hyperparameters",
    "train",
    "train_group",
]
