"""Training on the MuJoCo Warp twin: ``K`` runs of one algorithm, run ``k`` on world ``k``.

The learner is the algorithm's own (``rrls.agents.<algo>:Learner``, the same object the CPU
loop drives: one batched update for the ``K`` runs); only the physics moves to the GPU. Each
run keeps the paper's protocol of one env per run: its world resets on its own, and for DR
draws a new point of the set at every episode (from the twin's pool). The policies it returns
are evaluated where rrls evaluates everything, on CPU MuJoCo.

A lean loop, and device-resident: observations, actions, rewards, the replay and the updates
stay on the device, and nothing crosses to the host within a block of steps. Each run's random
inputs (warm-up actions, exploration noise, replay indices, smoothing noise) are drawn from its
own seeded generators on the CPU a block ahead and uploaded once per block
(``DeviceLearnerProtocol``), so a run's numbers depend neither on its group nor on the block
size; the episode returns come back once per block. On a GPU, PyTorch runs on the twin's CUDA
stream (no implicit synchronisation between the two), the twin's step is one CUDA graph and
each learner's acting and update variants are captured in CUDA graphs too (``graphs.Update``).

``rrls train --simulator warp`` (the training loop of every run, with
``rrls.agents.twin_envs``) adds checkpoints and resume, run directories, TensorBoard, periodic
evaluations and M2TD3, and crosses the host once per step. The adversarial games (RARL,
NR-MDP: an adversary acting every step) are refused by both.
"""

from __future__ import annotations

import contextlib
import math
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import torch

from rrls.agents.learner import DeviceLearnerProtocol
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
    block: int = 64,
) -> TwinTraining:
    """Train ``len(seeds)`` runs of ``algo`` on ``task``'s twin, world ``k`` for seed ``k``;
    ``on_progress(step, returns)`` every ``progress_every`` steps; random inputs drawn ``block``
    steps ahead (see the module's docstring)."""
    from rrls.twin import WarpTwin

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
    run_seeds = [RunSeeds(s) for s in seeds]
    twin = WarpTwin(
        task,
        len(seeds),
        uncertainty,
        domain_randomization=algorithm_info(algo).set_use == "random",
        seed=[s.integer("env") for s in run_seeds],
        device=device,
        array="torch",
        **(twin_options or {}),
    )
    dev = torch.device(device)
    learner = info.Learner(twin.cpu, config, run_seeds, dev)
    if not isinstance(learner, DeviceLearnerProtocol):
        twin.close()
        raise ValueError(
            f"{algo}'s learner has no device-resident methods (draw_ahead, act_tensor, put, "
            "update_drawn; docs/algorithms.md): train it with rrls train --simulator warp"
        )
    warm = NumpyGenerators(run_seeds, "warmup")
    low, high = twin.single_action_space.low, twin.single_action_space.high
    starts = int(getattr(config, "learning_starts", warmup(algo)))
    k = len(seeds)
    returns: list[list[float]] = [[] for _ in range(k)]
    start = time.perf_counter()
    with _twin_stream(twin, dev):
        obs = twin.reset()[0].clone()
        ret = torch.zeros(k, dtype=torch.float64, device=dev)
        done = 0
        while done < steps:
            # a block ends at every progress point, where the host reads the returns
            n = min(block, steps - done, progress_every - done % progress_every)
            draws = learner.draw_ahead(n)
            uniform = np.stack([rng.uniform(low, high, (n, len(low))) for rng in warm], 1)
            uniform_t = torch.from_numpy(uniform.astype(np.float32)).to(dev)
            ended_returns = torch.full((n, k), math.nan, dtype=torch.float64, device=dev)
            for j in range(n):
                step = done + j + 1
                row = {name: value[j] for name, value in draws.items()}
                actions = uniform_t[j] if step <= starts else learner.act_tensor(obs, row)
                next_obs, reward, terminated, truncated, out = twin.step(actions)
                ended = terminated | truncated
                # the transition's next state is the episode's last observation, not the reset's
                last = torch.where(ended[:, None], out["final_obs"], next_obs)
                learner.put(obs, actions, reward, last, terminated)
                if step > starts:
                    learner.update_drawn(step, row)
                ret += reward
                ended_returns[j] = torch.where(ended, ret, math.nan)
                ret.masked_fill_(ended, 0.0)
                obs = next_obs.clone()  # the twin writes its next observations in place
            done += n
            host = ended_returns.cpu().numpy()  # the block's one trip to the host
            for j, w in zip(*np.nonzero(~np.isnan(host)), strict=True):
                returns[w].append(float(host[j, w]))
            if on_progress is not None and done % progress_every == 0:
                on_progress(done, returns)
    wall = time.perf_counter() - start
    policies = [learner.export(w)["policy"] for w in range(k)]
    twin.close()
    return TwinTraining(policies, returns, steps, wall)


def _twin_stream(twin: Any, device: torch.device) -> Any:
    """On a GPU, PyTorch's work on the twin's CUDA stream: the twin's outputs are read and its
    actions written in stream order, without the legacy default stream's implicit waits."""
    if device.type != "cuda":
        return contextlib.nullcontext()
    import warp as wp

    return torch.cuda.stream(wp.stream_to_torch(twin.device))


__all__ = ["TwinTraining", "train_on_twin", "twin_refusal"]
