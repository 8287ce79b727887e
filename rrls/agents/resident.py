"""Training without leaving the device: ``K`` runs on the MuJoCo Warp twin (run ``k`` on world
``k``), for learners with the device-resident methods (``DeviceLearnerProtocol``: every
built-in algorithm). The twin's collector (``BlockCollector``) that the training driver
(``rrls.agents.driver``) runs for them in ``rrls train --simulator warp`` and in the library loop
``rrls.agents.on_twin.train_on_twin``; ``make_twin``, the one place their twin is built.

Observations, actions, rewards, the replay and the updates stay on the device. The host takes
part once per *block* of steps (``BLOCK``, shortened by the driver to end at every checkpoint,
periodic evaluation, loss log and progress point): it draws the block's random inputs from
each run's own generators (``draw_ahead``; the warm-up actions from the ``"warmup"`` stream)
and uploads them once, then reads back the block's episode ends, non-finite actions and last
losses once. So a run's numbers depend neither on its group nor on the block size, and nothing
is read back inside a block (``tests/test_twin_resident.py`` counts it).

Episodes are the twin's own: each world resets itself at termination and at the time limit,
its first state and DR point drawn from its seed and episode count (``WarpTwin``); DR draws
each episode's point from the whole box, its fields written on the device (``pool=0``). A
checkpoint holds each world's episode count, and a
resumed run starts the episode in progress again from its first state and point, as any twin
run, another draw of the same training (float32 physics on another device would not replay
it). M2TD3, whose learner chooses each episode's point, chooses it here on the device as the
episode begins (``begin_episodes``), and the twin writes it (``set_points``); with
``same_start`` it trains through each run's CPU env (``rrls.agents.twin_envs``). Adversaries
acting every step train here too: NR-MDP's learner
returns the executed action; RARL's twin takes both players' joint action and writes the
adversary's point into each world inside the step (``make_twin``).
"""

from __future__ import annotations

import contextlib
import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import torch

from rrls.agents.config import Diverged
from rrls.agents.driver import Advance
from rrls.agents.learner import DeviceLearnerProtocol
from rrls.agents.streams import RunSeeds, rng_state, set_rng_state
from rrls.algorithms import algorithm_info

#: env steps drawn ahead and run without reading back (a block also ends at every checkpoint,
#: periodic evaluation and loss log: ``rrls.agents.driver``)
BLOCK = 64


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
        begin = getattr(learner, "begin_episodes", None)  # a learner choosing its points
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
            if begin is not None:  # its point for each episode that begins
                self.twin.set_points(begin(ended, self.length, step, row))
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


def quiet_warp() -> None:
    """Warp's default logs a line per kernel module load: a training log keeps its own lines."""
    import warp as wp

    if wp.config.log_level == wp.LOG_INFO:
        wp.config.log_level = wp.LOG_WARNING


def make_twin(
    task: str,
    algo: str,
    seeds: list[int],
    uncertainty: Any,
    device: str,
    hyper: Any = None,
    **options: Any,
) -> Any:
    """The group's twin, the one place it is built for a device-resident run: world ``k``
    seeded from run ``k``'s ``"env"`` stream, DR (a new point of the whole box per episode per
    world, drawn from the world's own stream and written on the device, ``pool=0``: the CPU's
    ``DomainRandomization``, not a pool of points) for an algorithm whose row says it trains on
    random points, the adversary's columns of the action written into each world inside the
    step (``adversary=True``: RARL's game) for one whose row says an adversary moves the
    dynamics; ``options``: the rest of ``WarpTwin``'s (``max_episode_steps``...)."""
    from rrls.twin import WarpTwin

    use = algorithm_info(algo).set_use
    if use == "adversary":
        check_device_game(algo, hyper)
    quiet_warp()
    return WarpTwin(
        task,
        len(seeds),
        uncertainty,
        domain_randomization=use == "random",
        adversary=use == "adversary",
        chosen=use == "chosen",
        seed=[RunSeeds(s).integer("env") for s in seeds],
        device=device,
        array="torch",
        **{"pool": 0, **options},
    )


def check_device_game(algo: str, hyper: Any) -> None:
    """The twin plays RARL's plain game, the adversary's point written inside the step. A
    rate-limited adversary (TC-RMDP, with its observation variants: its parameters move on the
    host) trains on CPU MuJoCo: refused in one line before the twin is built."""
    if getattr(hyper, "rate_limit", None) is not None:
        raise ValueError(
            f"--simulator warp: {algo} with --rate-limit (TC-RMDP's game moves its parameters on "
            "the host) trains on CPU MuJoCo (--simulator mujoco)"
        )


def trains_on_device(config: Any, learner: type, hyper: Any = None) -> bool:
    """Whether ``rrls train`` runs this group here: the twin, a built-in row (it says whether
    the points are random) and a learner with the device-resident methods; not M2TD3's
    ``same_start`` (every episode from the run's one first state: each world resets itself from
    its own stream here, so those runs take the twin through each run's CPU env)."""
    return (
        config.simulator == "warp"
        and algorithm_info(config.algo) is not None
        and issubclass(learner, DeviceLearnerProtocol)
        and not getattr(hyper, "same_start", False)
    )


class BlockCollector:
    """The twin's collector for the driver (``rrls.agents.driver``): ``K`` runs on ``twin``'s
    worlds in blocks of up to ``block`` steps (default ``BLOCK``); ``learner`` is built (and its
    state loaded); ``starts``: the random warm-up's length; ``seeds``, ``algo``: named in
    ``Diverged``."""

    def __init__(
        self,
        twin: Any,
        learner: Any,
        seeds: list[int],
        starts: int,
        algo: str,
        device: torch.device,
        block: int | None = None,
    ) -> None:
        self.twin, self.learner, self.seeds = twin, learner, seeds
        self.starts, self.algo, self.device = starts, algo, device
        self.block = BLOCK if block is None else block
        self.warmup = [RunSeeds(s).numpy("warmup") for s in seeds]
        self.worlds = Worlds(twin, device, self.warmup)

    def running(self) -> contextlib.AbstractContextManager[Any]:
        return twin_stream(self.twin, self.device)

    def start(self, states: list[dict[str, Any] | None]) -> None:
        """A fresh reset, or the loop's streams as saved and the episodes in progress begun
        again (each world's episode count: the same first state and point)."""
        begin = getattr(self.learner, "begin_episodes", None)  # a learner choosing the points
        if states[0] is None:
            self.worlds.start()
            if begin is not None:  # the first episodes' points, from one step's draws
                row = {name: value[0] for name, value in self.learner.draw_ahead(1).items()}
                every = torch.ones(self.twin.num_envs, dtype=torch.bool, device=self.device)
                self.twin.set_points(begin(every, None, 0, row))
            return
        for k, state in enumerate(states):
            set_rng_state(self.warmup[k], state["warmup"])
        # a checkpoint without the count: the run's episodes so far, the next one in progress
        counts = [state.get("twin_episode", int(state["episodes"]) + 1) for state in states]
        self.worlds.start(np.array(counts))
        if begin is not None:  # the episodes in progress at their points again
            self.twin.set_points(self.learner.episode_points())

    def advance(self, step: int, n: int) -> Advance:
        block = self.worlds.block(self.learner, step, n, self.starts)
        check_finite(block, step, self.seeds, self.algo)
        return Advance(ended(block), block.losses)

    def next_episode(self, k: int, step: int) -> None:
        """Nothing: each world resets itself."""

    def state(self, k: int) -> dict[str, Any]:
        return {"warmup": rng_state(self.warmup[k]), "twin_episode": int(self.twin.episodes()[k])}


__all__ = [
    "BLOCK",
    "Block",
    "BlockCollector",
    "Worlds",
    "check_finite",
    "ended",
    "make_twin",
    "quiet_warp",
    "trains_on_device",
    "twin_stream",
]
