"""Baselines on one TD3 core (needs the ``train`` extra: torch, tensorboard).

``train(config)`` dispatches to the algorithm's module: ``td3``, ``dr``, ``rarl``, ``nrmdp``,
``m2td3`` — one readable file each, the loop visible top to bottom.
"""

from __future__ import annotations

import importlib
from pathlib import Path

from rrls.agents.common import ALGOS, Interrupted, TrainConfig


def default_uncertainty(algo: str, task: str) -> str:
    """The paper's set: RARL's forces for RARL, the 3D parameter set otherwise (2D for IP)."""
    from rrls.tasks import get_task

    if algo == "rarl":
        return "rarl"
    return "2d" if get_task(task).key == "invertedpendulum" else "3d"


def train(config: TrainConfig, resume: bool = False) -> Path:
    """Run ``config.algo``; returns the run directory (``policy.npz``, ``run.json``, ``tb/``)."""
    if config.algo not in ALGOS:
        raise ValueError(f"unknown algorithm {config.algo!r}; valid: {', '.join(ALGOS)}")
    module = importlib.import_module(f"rrls.agents.{config.algo}")
    return module.train(config, resume=resume)


__all__ = ["ALGOS", "Interrupted", "TrainConfig", "default_uncertainty", "train"]
