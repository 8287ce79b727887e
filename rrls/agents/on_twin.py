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

from rrls.agents.driver import Driver, drive
from rrls.agents.learner import DeviceLearnerProtocol
from rrls.agents.lookup import algorithm, warm_up
from rrls.agents.resident import BLOCK, SharedBlocks, make_part, make_shared_twin
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
    progress = None if on_progress is None else (lambda step, out: on_progress(step, out[algo]))
    return train_together(
        {algo: seeds},
        task,
        steps,
        uncertainty=uncertainty,
        device=device,
        hyper={algo: hyper or {}},
        twin_options=twin_options,
        on_progress=progress,
        progress_every=progress_every,
        block=block,
    )[algo]


def train_together(
    algos: dict[str, tuple[int, ...]],
    task: str = "hopper",
    steps: int = 100_000,
    *,
    uncertainty: str | None = None,
    device: str = "cuda",
    hyper: dict[str, dict[str, Any]] | None = None,
    twin_options: dict[str, Any] | None = None,
    on_progress: Any = None,
    progress_every: int = 1000,
    block: int = BLOCK,
) -> dict[str, TwinTraining]:
    """Train several algorithms' runs on one twin, ``algos`` ``{algo: seeds}``: each
    algorithm's worlds in its own mode (``WarpTwin(modes=...)``), its learner updating its own
    runs, one twin step for all of them, so a step's latency is paid once. A run's numbers are
    those it has trained alone (``train_on_twin``). ``hyper``: ``{algo: overrides}``;
    ``on_progress(step, {algo: returns})``."""
    if not algos:
        raise ValueError("algos: give at least one algorithm with its seeds")
    for algo, seeds in algos.items():
        why = twin_refusal(algo)
        if why is not None:
            raise ValueError(f"{algo} does not train on the Warp twin here: {why}")
        if not seeds:
            raise ValueError(f"seeds of {algo}: give at least one")
    for name, value in (("steps", steps), ("block", block), ("progress_every", progress_every)):
        if not isinstance(value, int) or value < 1:
            raise ValueError(f"{name} must be a positive integer, got {value!r}")
    hyper = hyper or {}
    unknown = sorted(set(hyper) - set(algos))
    if unknown:
        raise ValueError(f"hyper names {', '.join(unknown)}; valid: {', '.join(algos)}")
    configs = {a: algorithm(a).Config(**hyper.get(a, {})) for a in algos}
    uncertainty = uncertainty or default_set(task)  # the twin's own default, named for the env
    groups = [(a, list(seeds), configs[a]) for a, seeds in algos.items()]
    twin = make_shared_twin(task, groups, uncertainty, device, **(twin_options or {}))
    dev = torch.device(device)
    returns = {a: [[] for _ in seeds] for a, seeds in algos.items()}
    try:
        parts, lo = [], 0
        for algo, seeds in algos.items():
            learner = _learner(algo, task, uncertainty, configs[algo], twin, seeds, dev)
            parts.append(make_part(twin, learner, list(seeds), warm_up(configs[algo]), algo, lo))
            lo += len(seeds)
        shared = SharedBlocks(twin, parts, dev, block)
        drivers = []
        for algo, part, collector in zip(algos, parts, shared.collectors()):
            first = not drivers and on_progress is not None
            drivers.append(
                Driver(
                    part.learner,
                    collector,
                    group=len(part.seeds),
                    steps=steps,
                    starts=part.starts,
                    on_episode=lambda k, step, ret, mine=returns[algo]: mine[k].append(ret),
                    on_progress=(lambda step: on_progress(step, returns)) if first else None,
                    progress_every=progress_every,
                )
            )
        start = time.perf_counter()
        drive(drivers, [[None] * len(part.seeds) for part in parts])
        wall = time.perf_counter() - start
        out = {}
        for algo, part in zip(algos, parts):
            policies = [part.learner.export(k)["policy"] for k in range(len(part.seeds))]
            out[algo] = TwinTraining(policies, returns[algo], steps, wall)
    finally:
        twin.close()
    return out


def _learner(
    algo: str,
    task: str,
    uncertainty: str,
    config: Any,
    twin: Any,
    seeds: tuple[int, ...],
    device: torch.device,
) -> Any:
    """``algo``'s learner for ``seeds``' runs on the twin (RARL's reads both players' spaces
    from its game's env, M2TD3's its set from its env; the others the twin's)."""
    info = algorithm(algo)
    use = algorithm_info(algo).set_use
    game = info.make_env(task, uncertainty, config) if use in ("adversary", "chosen") else None
    try:
        learner = info.Learner(game or twin.cpu, config, [RunSeeds(s) for s in seeds], device)
    finally:
        if game is not None:
            game.close()
    if not isinstance(learner, DeviceLearnerProtocol):
        raise ValueError(
            f"{algo}'s learner has no device-resident methods (draw_ahead, act_tensor, put, "
            "update_drawn; docs/algorithms.md): train it with rrls train --simulator warp"
        )
    return learner


__all__ = ["TwinTraining", "train_on_twin", "train_together", "twin_refusal"]
