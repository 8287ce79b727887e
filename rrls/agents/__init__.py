"""Baselines in plain PyTorch on one training loop (needs the ``train`` extra: torch,
tensorboard).

``train(config)`` runs the loop (``rrls.agents.loop``) with an algorithm's learner
(``rrls.agents.algos``): ``td3``, ``dr``, ``rarl``, ``nrmdp``, ``m2td3`` (the paper's five),
``sac``, ``sacdr`` — one file each,
holding its paper reference, its hyper-parameters (``Config``) and its ``Learner``
(``rrls.agents.learner``: the protocol third-party learners implement too, see
``docs/algorithms.md``).
"""

from __future__ import annotations

from rrls.algorithms import built_in
from rrls.deprecation import moved_modules
from rrls.lazy import lazy_exports

ALGOS = built_in()  # the built-in algorithms' names (rrls.algorithms.ALGORITHMS is the table)

#: where each public name lives, imported on first use (PEP 562): ``import rrls.agents`` and
#: its torch-free modules (``rrls.agents.config``: a run's settings, read by ``rrls benchmark``'s
#: options) do not import torch; ``from rrls.agents import train`` does
_WHERE = {
    **dict.fromkeys(["Diverged", "Interrupted", "TrainConfig", "benchmark_set"], "config"),
    "task_env": "envs",
    "hp": "hparams",
    **dict.fromkeys(
        ["DeviceLearnerProtocol", "Learner", "LearnerProtocol", "StateLayoutError"], "learner"
    ),
    **dict.fromkeys(["ResolvedRun", "algorithm", "hyperparameters", "resolve_run"], "lookup"),
    **dict.fromkeys(["train", "train_group"], "loop"),
    **dict.fromkeys(
        [
            "Actor",
            "Critic",
            "GaussianActor",
            "NumpyActor",
            "deterministic",
            "polyak",
            "to_mlp_policy",
        ],
        "nets",
    ),
    **dict.fromkeys(["ReplayBuffer", "transition_fields"], "replay"),
    **dict.fromkeys(["Generators", "NumpyGenerators", "RunSeeds"], "streams"),
}


#: the algorithms' files moved to ``rrls.agents.algos`` (``rrls.agents.td3`` still imports, and
#: warns: stored plug-in paths and user code keep working)
__getattr__, __dir__ = lazy_exports(
    __name__,
    _WHERE,
    globals(),
    moved_modules({f"rrls.agents.{a}": f"rrls.agents.algos.{a}" for a in ALGOS}),
)


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
