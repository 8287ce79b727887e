"""Training on the MuJoCo Warp twin: ``K`` runs of one algorithm, run ``k`` on world ``k``.

The learner is the algorithm's own (``rrls.agents.<algo>:Learner``, the same object the CPU
loop drives: one batched update for the ``K`` runs); only the physics moves to the GPU. Each
run keeps the paper's protocol of one env per run: its world resets on its own, and for DR
draws a new point of the set at every episode (from the twin's pool). The policies it returns
are evaluated where rrls evaluates everything, on CPU MuJoCo.

A lean loop for measuring the twin's throughput; ``rrls train --simulator warp`` (the training
loop of every run, with ``rrls.agents.twin_envs``) adds checkpoints and resume, run
directories, TensorBoard, periodic evaluations and M2TD3. The adversarial games (RARL, NR-MDP:
an adversary acting every step) are refused by both.
Observations and actions cross to the host once per step (``K`` rows each), where the learners'
seeded exploration draws live.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import torch

from rrls.agents.lookup import algorithm
from rrls.agents.streams import NumpyGenerators, RunSeeds
from rrls.algorithms import algorithm_info, warmup
from rrls.twin.tasks import not_on_twin


def twin_refusal(algo: str) -> str | None:
    """Why this library loop does not train ``algo`` (its row's ``set_use``), or None: an
    adversary acting every step (no twin path), a learner choosing each episode's point
    (``rrls train --simulator warp`` trains it: the CPU env of each run takes the learner's point
    at every reset and the world copies it), a name without a row."""
    info = algorithm_info(algo)
    if info is None:
        return "no algorithm of that name"
    why = not_on_twin(algo)
    if why is not None:
        return why
    if info.set_use == "chosen":
        return "it picks each episode's point itself: train it with rrls train --simulator warp"
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
) -> TwinTraining:
    """Train ``len(seeds)`` runs of ``algo`` on ``task``'s twin, world ``k`` for seed ``k``;
    ``on_progress(step, returns)`` every ``progress_every`` steps."""
    from rrls.twin import WarpTwin

    why = twin_refusal(algo)
    if why is not None:
        raise ValueError(f"{algo} does not train on the Warp twin here: {why}")
    if not seeds:
        raise ValueError("seeds: give at least one")
    info = algorithm(algo)
    config = info.Config(**(hyper or {}))
    run_seeds = [RunSeeds(s) for s in seeds]
    twin = WarpTwin(
        task,
        len(seeds),
        uncertainty,
        domain_randomization=algorithm_info(algo).set_use == "random",
        seed=[s.integer("env") for s in run_seeds],
        device=device,
        **(twin_options or {}),
    )
    learner = info.Learner(twin.cpu, config, run_seeds, torch.device(device))
    explore = NumpyGenerators(run_seeds, "warmup")
    space = twin.single_action_space
    starts = int(getattr(config, "learning_starts", warmup(algo)))
    k = len(seeds)
    returns: list[list[float]] = [[] for _ in range(k)]
    ret = np.zeros(k)
    obs, _ = twin.reset()
    infos = [{} for _ in range(k)]
    start = time.perf_counter()
    for step in range(1, steps + 1):
        if step <= starts:
            actions = np.stack([rng.uniform(space.low, space.high) for rng in explore])
        else:
            actions = np.stack(learner.act(obs))
        next_obs, reward, terminated, truncated, info_ = twin.step(actions.astype(np.float32))
        ended = terminated | truncated
        # the transition's next state is the episode's last observation, not the reset's
        last = np.where(ended[:, None], info_["final_obs"], next_obs)
        learner.observe(obs, list(actions), reward.astype(np.float64), last, terminated, infos)
        if step > starts:
            learner.update(step)
        ret += reward
        for w in np.flatnonzero(ended):
            returns[w].append(float(ret[w]))
            ret[w] = 0.0
        obs = next_obs
        if on_progress is not None and step % progress_every == 0:
            if device.startswith("cuda"):
                torch.cuda.synchronize()
            on_progress(step, returns)
    if device.startswith("cuda"):
        torch.cuda.synchronize()
    wall = time.perf_counter() - start
    policies = [learner.export(w)["policy"] for w in range(k)]
    twin.close()
    return TwinTraining(policies, returns, steps, wall)


__all__ = ["TwinTraining", "train_on_twin", "twin_refusal"]
