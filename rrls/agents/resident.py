"""Training without leaving the device: ``K`` runs on the MuJoCo Warp twin (run ``k`` on world
``k``), for learners with the device-resident methods (``DeviceLearnerProtocol``: TD3, DR, SAC,
SAC-DR). What ``rrls train --simulator warp`` runs for them, and the library loop
``rrls.agents.on_twin.train_on_twin``.

Observations, actions, rewards, the replay and the updates stay on the device. The host takes
part once per *block* of steps (``BLOCK``, shortened to end at every checkpoint, periodic
evaluation and loss log): it draws the block's random inputs from each run's own generators
(``draw_ahead``; the loop's warm-up actions from the ``"warmup"`` stream) and uploads them once,
then reads back the block's episode ends, non-finite actions and last losses once. So a run's
numbers depend neither on its group nor on the block size, and nothing is read back inside a
block (``tests/test_twin_resident.py`` counts it).

Episodes are the twin's own: each world resets itself at termination and at the time limit,
its first state and DR point drawn from its seed and episode count (``WarpTwin``); DR draws
from the twin's pool of points of the set. A checkpoint holds each world's episode count, and a
resumed run starts the episode in progress again from its first state and point, as any twin
run, another draw of the same training (float32 physics on another device would not replay
it). M2TD3, whose learner chooses each episode's point, trains through the CPU env of each run
(``rrls.agents.twin_envs``); adversaries acting every step (RARL, NR-MDP) have no twin path.
"""

from __future__ import annotations

import contextlib
import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import torch

from rrls.agents.config import Diverged
from rrls.agents.learner import DeviceLearnerProtocol, check_runs_first, run_slice
from rrls.agents.run import export_policies
from rrls.agents.streams import RunSeeds, rng_state, set_rng_state
from rrls.algorithms import algorithm_info

#: env steps drawn ahead and run without reading back (a block also ends at every checkpoint,
#: periodic evaluation and loss log)
BLOCK = 64
#: the loop logs the learner's losses every this many steps (as the CPU loop does)
LOSS_EVERY = 1000


def twin_stream(twin: Any, device: torch.device) -> Any:
    """On a GPU, PyTorch's work on the twin's CUDA stream: the twin's outputs are read and its
    actions written in stream order, without the legacy default stream's implicit waits."""
    if device.type != "cuda":
        return contextlib.nullcontext()
    import warp as wp

    return torch.cuda.stream(wp.stream_to_torch(twin.device))


@dataclass
class Block:
    """What one block leaves for the host: per step and run, the return and length of an
    episode that ended there (NaN and 0 elsewhere) and whether the action was non-finite; the
    last update's losses."""

    returns: torch.Tensor
    lengths: torch.Tensor
    bad: torch.Tensor
    losses: dict[str, torch.Tensor]


class Worlds:
    """The group's worlds and each run's episode in progress, on the device."""

    def __init__(self, twin: Any, device: torch.device, warmup: list[np.random.Generator]):
        self.twin, self.device, self.warmup = twin, device, warmup
        self.low = twin.single_action_space.low
        self.high = twin.single_action_space.high
        k = twin.num_envs
        self.ret = torch.zeros(k, dtype=torch.float64, device=device)
        self.length = torch.zeros(k, dtype=torch.int64, device=device)
        self.obs: torch.Tensor | None = None

    def start(self, episodes: np.ndarray | None = None) -> None:
        """Every world's first state: a fresh reset, or the episodes in progress again."""
        obs = self.twin.reset()[0] if episodes is None else self.twin.restart(episodes)
        self.obs = obs.clone()

    def block(self, learner: Any, first: int, n: int, starts: int) -> Block:
        """Env steps ``first + 1 .. first + n``: act (uniformly before ``starts``), step, store,
        update (after ``starts``), on the device."""
        k = self.twin.num_envs
        draws = learner.draw_ahead(n)
        uniform = np.stack(
            [g.uniform(self.low, self.high, (n, len(self.low))) for g in self.warmup], 1
        )
        uniform_t = torch.from_numpy(uniform.astype(np.float32)).to(self.device)
        out = Block(
            torch.full((n, k), math.nan, dtype=torch.float64, device=self.device),
            torch.zeros((n, k), dtype=torch.int64, device=self.device),
            torch.zeros((n, k), dtype=torch.bool, device=self.device),
            {},
        )
        for j in range(n):
            step = first + j + 1
            row = {name: value[j] for name, value in draws.items()}
            if step <= starts:
                actions = uniform_t[j]
            else:
                actions = learner.act_tensor(self.obs, row)
                out.bad[j] = ~torch.isfinite(actions).all(1)
            next_obs, reward, terminated, truncated, info = self.twin.step(actions)
            ended = terminated | truncated
            # the transition's next state is the episode's last observation, not the reset's
            last = torch.where(ended[:, None], info["final_obs"], next_obs)
            learner.put(self.obs, actions, reward, last, terminated)
            if step > starts:
                out.losses = learner.update_drawn(step, row)
            self.ret += reward
            self.length += 1
            out.returns[j] = torch.where(ended, self.ret, math.nan)
            out.lengths[j] = torch.where(ended, self.length, 0)
            self.ret.masked_fill_(ended, 0.0)
            self.length.masked_fill_(ended, 0)
            self.obs = next_obs.clone()  # the twin writes its next observations in place
        return out


def ended(block: Block) -> list[tuple[int, int, float, int]]:
    """The block's episode ends, ``(step offset, run, return, length)`` in step order (the
    block's one read back of them)."""
    returns, lengths = block.returns.cpu().numpy(), block.lengths.cpu().numpy()
    rows, runs = np.nonzero(~np.isnan(returns))
    return [(int(j), int(w), float(returns[j, w]), int(lengths[j, w])) for j, w in zip(rows, runs)]


def check_finite(block: Block, first: int, seeds: list[int], algo: str) -> None:
    """Stop at a block's first non-finite action (``Diverged``, as the CPU loop does)."""
    bad = block.bad.cpu().numpy()
    if bad.any():
        j, w = (int(x[0]) for x in np.nonzero(bad))
        raise Diverged(
            f"training stopped at step {first + j + 1}: {algo} returned a non-finite action for "
            f"seed {seeds[w]}; nothing was written past the last checkpoint (the learner "
            "diverged: lower its learning rate or check its update)"
        )


def make_twin(config: Any, seeds: list[int]) -> Any:
    """The group's twin: world ``k`` seeded from run ``k``'s ``"env"`` stream, DR (a new point
    per episode per world) for an algorithm whose row says it trains on random points."""
    import warp as wp

    from rrls.twin import WarpTwin

    if wp.config.log_level == wp.LOG_INFO:  # warp's default: a line per kernel module load
        wp.config.log_level = wp.LOG_WARNING  # a training log keeps its own lines
    return WarpTwin(
        config.task,
        len(seeds),
        config.training_set(),
        domain_randomization=algorithm_info(config.algo).set_use == "random",
        seed=[RunSeeds(s).integer("env") for s in seeds],
        pool_seed=0,
        device=config.device,
        array="torch",
        max_episode_steps=config.max_episode_steps,
    )


def trains_on_device(config: Any, learner: type) -> bool:
    """Whether ``rrls train`` runs this group here: the twin, a built-in row (it says whether
    the points are random) and a learner with the device-resident methods."""
    return (
        config.simulator == "warp"
        and algorithm_info(config.algo) is not None
        and issubclass(learner, DeviceLearnerProtocol)
    )


def collect(
    learner: Any, twin: Any, runs: list[Any], states: list, on_episode, threads, starts: int
) -> None:
    """The collection loop of ``runs`` (one group, at the same step) on ``twin``'s worlds;
    ``learner`` is built and its state loaded (``rrls.agents.loop``); ``starts``: the random
    warm-up's length."""
    first = runs[0].config
    device, group = torch.device(first.device), len(runs)
    seeds = [RunSeeds(run.config.seed) for run in runs]
    warmup = [s.numpy("warmup") for s in seeds]
    metas = [run.metadata(twin.cpu) for run in runs]
    worlds = Worlds(twin, device, warmup)
    resumed = states[0] is not None
    step, steps = runs[0].step, first.steps
    bar = runs[0].progress(group)
    try:
        with twin_stream(twin, device):
            if resumed:  # the loop's streams as saved; the episodes in progress begin again
                for k, state in enumerate(states):
                    set_rng_state(warmup[k], state["warmup"])
                counts = [
                    state.get("twin_episode", runs[k].episodes + 1)
                    for k, state in enumerate(states)
                ]
                worlds.start(np.array(counts))
            else:
                worlds.start()
            while step < steps:
                due = [runs[0].steps_to_checkpoint(), runs[0].steps_to_eval()]
                n = min(BLOCK, steps - step, LOSS_EVERY - step % LOSS_EVERY, *filter(None, due))
                block = worlds.block(learner, step, n, starts)
                check_finite(block, step, [r.config.seed for r in runs], first.algo)
                for j, k, ret, length in ended(block):
                    runs[k].step = step + j + 1
                    extra = learner.episode_end(k, ret, length)
                    runs[k].episode_end(ret, length, **extra)
                    if on_episode is not None:
                        on_episode(k, step + j + 1, ret)
                step += n
                for run in runs:
                    run.step = step
                threads.poll()
                if step > starts and step % LOSS_EVERY == 0 and block.losses:
                    values = {name: v.cpu().tolist() for name, v in block.losses.items()}
                    for k, run in enumerate(runs):
                        run.log({f"losses/{name}": v[k] for name, v in values.items()})
                if runs[0].eval_due():
                    for k, run in enumerate(runs):
                        run.evaluate(export_policies(learner, k, metas[k])["policy"])
                if runs[0].checkpoint_due():
                    state = learner.state_dict()
                    check_runs_first(state, group)
                    counts = twin.episodes()
                    for k, run in enumerate(runs):
                        run.save(
                            {
                                "learner": run_slice(state, k),
                                "warmup": rng_state(warmup[k]),
                                "twin_episode": int(counts[k]),
                            }
                        )
                    runs[0].check_stop()
                bar.update(group * n)
    finally:
        bar.close()
    for k, run in enumerate(runs):
        run.finish(
            export_policies(learner, k, metas[k]), {"steps": run.step, "episodes": run.episodes}
        )


__all__ = [
    "BLOCK",
    "Block",
    "Worlds",
    "check_finite",
    "collect",
    "ended",
    "make_twin",
    "trains_on_device",
    "twin_stream",
]
