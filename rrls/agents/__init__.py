"""Baselines in plain PyTorch on one training loop (needs the ``train`` extra: torch,
tensorboard).

``train(config)`` runs the loop (``rrls.agents.loop``) with an algorithm's learner: ``td3``,
``dr``, ``rarl``, ``nrmdp``, ``m2td3`` (the paper's five), ``sac``, ``sacdr`` — one file each,
holding its paper reference, its hyper-parameters (``Config``) and its ``Learner``
(``rrls.agents.learner``: the protocol third-party learners implement too, see
``docs/algorithms.md``).
"""

from __future__ import annotations

from rrls.agents.config import Diverged, Interrupted, TrainConfig, benchmark_set
from rrls.agents.envs import task_env
from rrls.agents.hparams import hp
from rrls.agents.learner import (
    DeviceLearnerProtocol,
    Learner,
    LearnerProtocol,
    StateLayoutError,
)
from rrls.agents.lookup import ResolvedRun, algorithm, hyperparameters, resolve_run
from rrls.agents.loop import train, train_group
from rrls.agents.nets import (
    Actor,
    Critic,
    GaussianActor,
    NumpyActor,
    deterministic,
    polyak,
    to_mlp_policy,
)
from rrls.agents.replay import ReplayBuffer, transition_fields
from rrls.agents.streams import Generators, NumpyGenerators, RunSeeds
from rrls.algorithms import built_in

ALGOS = built_in()  # the built-in algorithms' names (rrls.algorithms.ALGORITHMS is the table)

__all__ = [
    # running
    "ALGOS",
    "Diverged",
    "Interrupted",
    "TrainConfig",
    "algorithm",
    "benchmark_set",
    "hyperparameters",
    "resolve_run",
    "ResolvedRun",
    "train",
    "train_group",
    # the learner protocol and its building blocks (what docs/examples/ddpg.py is made of)
    "Actor",
    "Critic",
    "DeviceLearnerProtocol",
    "GaussianActor",
    "Generators",
    "Learner",
    "LearnerProtocol",
    "NumpyActor",
    "NumpyGenerators",
    "ReplayBuffer",
    "RunSeeds",
    "StateLayoutError",
    "deterministic",
    "hp",
    "polyak",
    "task_env",
    "to_mlp_policy",
    "transition_fields",
]
