"""Baselines in plain PyTorch on one training loop (needs the ``train`` extra: torch,
tensorboard).

``train(config)`` runs the loop (``rrls.agents.loop``) with an algorithm's learner: ``td3``,
``dr``, ``rarl``, ``nrmdp``, ``m2td3`` (the paper's five), ``sac``, ``sacdr`` — one file each,
holding its paper reference, its hyper-parameters (``Config``) and its ``Learner``
(``rrls.agents.learner``: the protocol third-party learners implement too, see
``docs/algorithms.md``).
"""

from __future__ import annotations

from rrls.agents.common import (
    ALGOS,
    Diverged,
    Interrupted,
    TrainConfig,
    algorithm,
    benchmark_set,
    hyperparameters,
)
from rrls.agents.learner import Learner
from rrls.agents.loop import train, train_group

__all__ = [
    "ALGOS",
    "Diverged",
    "Interrupted",
    "Learner",
    "TrainConfig",
    "algorithm",
    "benchmark_set",
    "hyperparameters",
    "train",
    "train_group",
]
