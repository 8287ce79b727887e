"""Training on the MuJoCo Warp twin: ``K`` runs of one algorithm, run ``k`` on world ``k``.

The learner is the algorithm's own (``rrls.agents.<algo>:Learner``, the same object the CPU
loop drives: one batched update for the ``K`` runs); only the physics moves to the GPU. Each
run keeps the paper's protocol of one env per run: its world resets on its own, and for DR
draws a new point of the box at every episode (on the device). The policies it returns
are evaluated where rrls evaluates everything, on CPU MuJoCo.

The training driver of ``rrls train`` (``rrls.agents.driver``) with the twin's device-resident
collector (``rrls.agents.resident``: nothing read back inside a block, each run's random inputs
drawn a block ahead from its own generators), without run directories, so without loss logs,
checkpoints or periodic evaluations: for measuring the twin's throughput and for scripts.
``rrls train --simulator warp`` adds those. Every built-in algorithm trains here: the
adversarial games (RARL, NR-MDP), and M2TD3, whose points the twin takes from its learner.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any

import torch

from rrls.agents.driver import Driver
from rrls.agents.learner import DeviceLearnerProtocol
from rrls.agents.lookup import algorithm, warm_up
from rrls.agents.resident import BLOCK, BlockCollector, make_twin
from rrls.agents.streams import RunSeeds
from rrls.algorithms import algorithm_info
from rrls.twin.catalog import not_on_twin
from rrls.twin.env import default_set


def twin_refusal(algo: str) -> str | None:
    """Why this library loop does not train ``algo``, or None: a name without a row (every
    built-in algorithm trains here; a learner choosing each episode's point, M2TD3, chooses it
    on the device and the twin writes it)."""
    info = algorithm_info(algo)
    if info is None:
        return "no algorithm of that name"
    why = not_on_twin(algo)
    if why is not None:
        return why
    return None


@dataclass
class TwinTraining:
    """What a twin run gives back: each run's final policy (an ``MLPPolicy``), its episode
    returns in order, the env steps taken per run and the wall time."""

    policies: list[Any]
    returns: list[list[float]] = field(default_factory=list)
    steps: int = 0
    wall_s: float = 0.0

    @property
    def steps_per_second(self) -> float:
        """Aggregated env steps per second (all runs)."""
        return len(self.policies) * self.steps / self.wall_s if self.wall_s else 0.0


def train_on_twin(
    algo: str = "td3",
    task: str = "hopper",
    seeds: tuple[int, ...] = (0,),
    steps: int = 100_000,
    *,
    uncertainty: str | None = None,
    device: str = "cuda",
    hyper: dict[str, Any] | None = None,
    twin_options: dict[str, Any] | None = None,
    on_progress: Any = None,
    progress_every: int = 1000,
    block: int = BLOCK,
) -> TwinTraining:
    """Train ``len(seeds)`` runs of ``algo`` on ``task``'s twin, world ``k`` for seed ``k``;
    ``on_progress(step, returns)`` every ``progress_every`` steps; random inputs drawn ``block``
    steps ahead (see the module's docstring)."""
    why = twin_refusal(algo)
    if why is not None:
        raise ValueError(f"{algo} does not train on the Warp twin here: {why}")
    if not seeds:
        raise ValueError("seeds: give at least one")
    for name, value in (("steps", steps), ("block", block), ("progress_every", progress_every)):
        if not isinstance(value, int) or value < 1:
            raise ValueError(f"{name} must be a positive integer, got {value!r}")
    info = algorithm(algo)
    config = info.Config(**(hyper or {}))
    uncertainty = uncertainty or default_set(task)  # the twin's own default, named for the env
    twin = make_twin(task, algo, list(seeds), uncertainty, device, config, **(twin_options or {}))
    dev = torch.device(device)
    # RARL's learner reads both players' spaces from its game's env, M2TD3 its set from its
    # env; the others the twin's
    game = info.make_env(task, uncertainty, config) if twin.adversary_dim or twin.chosen else None
    try:
        learner = info.Learner(game or twin.cpu, config, [RunSeeds(s) for s in seeds], dev)
    finally:
        if game is not None:
            game.close()
    if not isinstance(learner, DeviceLearnerProtocol):
        twin.close()
        raise ValueError(
            f"{algo}'s learner has no device-resident methods (draw_ahead, act_tensor, put, "
            "update_drawn; docs/algorithms.md): train it with rrls train --simulator warp"
        )
    starts = warm_up(config)
    returns: list[list[float]] = [[] for _ in seeds]
    collector = BlockCollector(twin, learner, list(seeds), starts, algo, dev, block)
    driver = Driver(
        learner,
        collector,
        group=len(seeds),
        steps=steps,
        starts=starts,
        on_episode=lambda k, step, ret: returns[k].append(ret),
        on_progress=None if on_progress is None else (lambda step: on_progress(step, returns)),
        progress_every=progress_every,
    )
    start = time.perf_counter()
    try:
        driver.run([None] * len(seeds))
        wall = time.perf_counter() - start
        policies = [learner.export(w)["policy"] for w in range(len(seeds))]
    finally:
        twin.close()
    return TwinTraining(policies, returns, steps, wall)


__all__ = ["TwinTraining", "train_on_twin", "twin_refusal"]
