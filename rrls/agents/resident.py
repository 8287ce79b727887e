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
each episode's point from the whole box, its fields written on the device (world mode ``random``). A
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
from dataclasses import dataclass, field
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


@dataclass
class Part:
    """One algorithm's runs on a twin (alone, or beside other algorithms' on a shared one): its
    learner, its worlds ``lo .. hi - 1`` (run ``k`` on world ``lo + k``), its random warm-up's
    length, the runs' warm-up generators and the action bounds they draw from (the protagonist's;
    with RARL's adversary the joint action's), the seeds and the algorithm named in errors."""

    learner: Any
    lo: int
    starts: int
    seeds: list[int]
    algo: str
    low: np.ndarray
    high: np.ndarray
    warmup: list[np.random.Generator] = field(default_factory=list)

    def __post_init__(self) -> None:
        if not self.warmup:
            self.warmup = [RunSeeds(s).numpy("warmup") for s in self.seeds]

    @property
    def worlds(self) -> slice:
        return slice(self.lo, self.lo + len(self.seeds))


def make_part(
    twin: Any, learner: Any, seeds: list[int], starts: int, algo: str, lo: int = 0
) -> Part:
    """``seeds``' runs of ``algo`` on ``twin``'s worlds from ``lo``, their warm-up drawn within
    the action those worlds take (the joint action where an adversary plays)."""
    space = twin.single_action_space
    width = twin.nu + (twin.adversary_dim if twin.world_modes[lo] == "adversary" else 0)
    return Part(learner, lo, starts, list(seeds), algo, space.low[:width], space.high[:width])


class Worlds:
    """The twin's worlds and each run's episode in progress, on the device."""

    def __init__(self, twin: Any, device: torch.device):
        self.twin, self.device = twin, device
        k = twin.num_envs
        self.ret = torch.zeros(k, dtype=torch.float64, device=device)
        self.length = torch.zeros(k, dtype=torch.int64, device=device)
        self.obs: torch.Tensor | None = None

    def start(self, episodes: np.ndarray | None = None) -> None:
        """Every world's first state: a fresh reset, or the episodes in progress again."""
        obs = self.twin.reset()[0] if episodes is None else self.twin.restart(episodes)
        self.obs = obs.clone()

    def block(self, parts: list[Part], first: int, n: int) -> list[Block]:
        """Env steps ``first + 1 .. first + n`` of every part: act (uniformly before its
        ``starts``), one twin step for all of them, store, update (after its ``starts``), on the
        device; each part's block."""
        width = self.twin.single_action_space.shape[0]
        draws = [part.learner.draw_ahead(n) for part in parts]
        begins = [getattr(part.learner, "begin_episodes", None) for part in parts]
        uniform = [self._uniform(part, n) for part in parts]
        out = [self._empty(n, len(part.seeds)) for part in parts]
        for j in range(n):
            step = first + j + 1
            rows = [{name: value[j] for name, value in d.items()} for d in draws]
            acts = []
            for part, row, u, o in zip(parts, rows, uniform, out):
                if step <= part.starts:
                    actions = u[j]
                else:
                    actions = part.learner.act_tensor(self.obs[part.worlds], row)
                    o.bad[j] = ~torch.isfinite(actions).all(1)
                acts.append(actions)
            joint = acts[0] if len(parts) == 1 else torch.cat([_wide(a, width) for a in acts])
            next_obs, reward, terminated, truncated, info = self.twin.step(joint)
            ended = terminated | truncated
            # the transition's next state is the episode's last observation, not the reset's
            last = torch.where(ended[:, None], info["final_obs"], next_obs)
            self.ret += reward
            self.length += 1
            for part, row, actions, begin, o in zip(parts, rows, acts, begins, out):
                w = part.worlds
                part.learner.put(self.obs[w], actions, reward[w], last[w], terminated[w])
                if step > part.starts:
                    o.losses = part.learner.update_drawn(step, row)
                o.returns[j] = torch.where(ended[w], self.ret[w], math.nan)
                o.lengths[j] = torch.where(ended[w], self.length[w], 0)
                if begin is not None:  # its point for each episode that begins
                    self.twin.set_points(begin(ended[w], self.length[w], step, row), part.lo)
            self.ret.masked_fill_(ended, 0.0)
            self.length.masked_fill_(ended, 0)
            self.obs = next_obs.clone()  # the twin writes its next observations in place
        return out

    def _uniform(self, part: Part, n: int) -> torch.Tensor:
        """The part's warm-up actions for ``n`` steps, from each run's own generator."""
        size = (n, len(part.low))
        uniform = np.stack([g.uniform(part.low, part.high, size) for g in part.warmup], 1)
        return torch.from_numpy(uniform.astype(np.float32)).to(self.device)

    def _empty(self, n: int, k: int) -> Block:
        return Block(
            torch.full((n, k), math.nan, dtype=torch.float64, device=self.device),
            torch.zeros((n, k), dtype=torch.int64, device=self.device),
            torch.zeros((n, k), dtype=torch.bool, device=self.device),
            {},
        )


def _wide(actions: torch.Tensor, width: int) -> torch.Tensor:
    """A part's actions widened to the shared twin's joint action (zeros where no adversary
    plays: those worlds read only the protagonist's columns)."""
    extra = width - actions.shape[1]
    if not extra:
        return actions
    return torch.cat([actions, actions.new_zeros((actions.shape[0], extra))], 1)


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
    world, drawn from the world's own stream and written on the device: the CPU's
    ``DomainRandomization``, not a pool of points) for an algorithm whose row says it trains on
    random points, the adversary's columns of the action written into each world inside the
    step (RARL's game) for one whose row says an adversary moves the dynamics, the learner's
    points (``set_points``) for one that chooses them; ``options``: the rest of ``WarpTwin``'s
    (``max_episode_steps``...)."""
    return make_shared_twin(task, [(algo, seeds, hyper)], uncertainty, device, **options)


def make_shared_twin(
    task: str,
    groups: list[tuple[str, list[int], Any]],
    uncertainty: Any,
    device: str,
    **options: Any,
) -> Any:
    """One twin for several algorithms' runs, ``groups`` of ``(algo, seeds, hyper)`` on
    consecutive worlds, each world in its algorithm's mode (``make_twin``'s, per world: the
    row's ``set_use``). A world's numbers are those it has on its group's twin alone."""
    from rrls.twin import WarpTwin

    modes, worlds = [], []
    for algo, seeds, hyper in groups:
        use = algorithm_info(algo).set_use
        if use == "adversary":
            check_device_game(algo, hyper)
        modes += [use] * len(seeds)
        worlds += [RunSeeds(s).integer("env") for s in seeds]
    quiet_warp()
    return WarpTwin(
        task,
        len(worlds),
        uncertainty,
        modes=modes,
        seed=worlds,
        device=device,
        array="torch",
        **options,
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


class SharedBlocks:
    """The twin's blocks for every part on it (one algorithm's runs, or several algorithms'
    sharing each twin step), stepped once for all of them; each part's driver reads its own
    through a :class:`BlockCollector`. ``block``: the most steps drawn ahead (``BLOCK``)."""

    def __init__(
        self, twin: Any, parts: list[Part], device: torch.device, block: int | None = None
    ) -> None:
        self.twin, self.parts, self.device = twin, parts, device
        self.block = BLOCK if block is None else block
        self.worlds = Worlds(twin, device)
        self._states: list[list[dict[str, Any] | None] | None] = [None] * len(parts)
        self._done: tuple[tuple[int, int], list[Advance]] | None = None

    def collectors(self) -> list[BlockCollector]:
        """One collector a part, for its driver (``rrls.agents.driver.drive``)."""
        return [BlockCollector(self, i) for i in range(len(self.parts))]

    def give(self, i: int, states: list[dict[str, Any] | None]) -> None:
        """Part ``i``'s checkpoints (None: a fresh start); the twin starts once all are given."""
        self._states[i] = states
        if all(s is not None for s in self._states):
            self._start([s for s in self._states if s is not None])

    def _start(self, states: list[list[dict[str, Any] | None]]) -> None:
        """A fresh reset, or the loop's streams as saved and the episodes in progress begun
        again (each world's episode count: the same first state and point)."""
        fresh = [s[0] is None for s in states]
        if all(fresh):
            self.worlds.start()
            for part in self.parts:  # a learner choosing the points: its first episodes'
                begin = getattr(part.learner, "begin_episodes", None)
                if begin is not None:  # from one step's draws
                    row = {name: value[0] for name, value in part.learner.draw_ahead(1).items()}
                    every = torch.ones(len(part.seeds), dtype=torch.bool, device=self.device)
                    self.twin.set_points(begin(every, None, 0, row), part.lo)
            return
        if any(fresh):
            raise ValueError("runs sharing a twin resume together: some have no checkpoint")
        counts = []
        for part, part_states in zip(self.parts, states):
            for k, state in enumerate(part_states):
                if state is None:
                    raise ValueError("runs sharing a twin resume together: some have no checkpoint")
                set_rng_state(part.warmup[k], state["warmup"])
                # a checkpoint without the count: the run's episodes, the next one in progress
                counts.append(state.get("twin_episode", int(state["episodes"]) + 1))
        self.worlds.start(np.array(counts))
        for part in self.parts:
            if getattr(part.learner, "begin_episodes", None) is not None:  # at their points
                self.twin.set_points(part.learner.episode_points(), part.lo)

    def advance(self, step: int, n: int) -> list[Advance]:
        """Steps ``step + 1 .. step + n`` of every part, once: each part's driver asks."""
        if self._done is None or self._done[0] != (step, n):
            blocks = self.worlds.block(self.parts, step, n)
            out = []
            for part, block in zip(self.parts, blocks):
                check_finite(block, step, part.seeds, part.algo)
                out.append(Advance(ended(block), block.losses))
            self._done = ((step, n), out)
        return self._done[1]

    def state(self, i: int, k: int) -> dict[str, Any]:
        part = self.parts[i]
        warmup = rng_state(part.warmup[k])
        return {"warmup": warmup, "twin_episode": int(self.twin.episodes()[part.lo + k])}


class BlockCollector:
    """The twin's collector for one part's driver (``rrls.agents.driver``): its runs' share of
    the blocks that :class:`SharedBlocks` steps for every part on the twin."""

    def __init__(self, shared: SharedBlocks, index: int = 0) -> None:
        self.shared, self.index = shared, index
        self.block = shared.block

    @classmethod
    def alone(
        cls,
        twin: Any,
        learner: Any,
        seeds: list[int],
        starts: int,
        algo: str,
        device: torch.device,
        block: int | None = None,
    ) -> BlockCollector:
        """The collector of one algorithm's ``K`` runs alone on ``twin`` (run ``k`` on world
        ``k``); ``learner`` is built (and its state loaded); ``starts``: the random warm-up's
        length; ``seeds``, ``algo``: named in ``Diverged``."""
        part = make_part(twin, learner, seeds, starts, algo)
        return cls(SharedBlocks(twin, [part], device, block))

    def running(self) -> contextlib.AbstractContextManager[Any]:
        if self.index:  # the first part's driver holds the twin's stream for all
            return contextlib.nullcontext()
        return twin_stream(self.shared.twin, self.shared.device)

    def start(self, states: list[dict[str, Any] | None]) -> None:
        self.shared.give(self.index, states)

    def advance(self, step: int, n: int) -> Advance:
        return self.shared.advance(step, n)[self.index]

    def next_episode(self, k: int, step: int) -> None:
        """Nothing: each world resets itself."""

    def state(self, k: int) -> dict[str, Any]:
        return self.shared.state(self.index, k)


__all__ = [
    "BLOCK",
    "Block",
    "BlockCollector",
    "Part",
    "SharedBlocks",
    "Worlds",
    "check_finite",
    "ended",
    "make_part",
    "make_shared_twin",
    "make_twin",
    "quiet_warp",
    "trains_on_device",
    "twin_stream",
]
