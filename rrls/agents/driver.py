"""The one training driver: a group of runs' cadence, written once for every way of collecting
experience.

A *collector* steps the group's envs and learns (acting, storing, updating; the random warm-up
before ``learning_starts``) for a block of env steps, and reports what happened: each episode
that ended (step, run, return, length) and the last update's losses. Two exist: the CPU envs
stepped one step at a time (``rrls.agents.stepwise.StepCollector``, also the twin's envs for
learners without the device methods) and the MuJoCo Warp twin's device-resident blocks
(``rrls.agents.resident.BlockCollector``).

The driver owns everything else, the same for both, so that a run's files say the same things
at the same steps whichever collector stepped it: how far a block may go (it ends at every
checkpoint, periodic evaluation, loss log and progress point, where the host must look), each
episode end (the learner's hook, the run's curves, ``on_episode``, then the collector's next
episode), the losses logged every ``LOSS_EVERY`` steps, the periodic evaluations, the
checkpoints (every ``checkpoint_every`` steps and at Ctrl-C, at the end of the block it came
in), the progress bar and the finish (each run's exported policies and ``run.json``).

What happens at one step, in order: the update (the collector's), the loss log, the periodic
evaluation, then the episodes that ended there; the checkpoint comes last, after the next
episodes began. Without run directories (``rrls.agents.on_twin.train_on_twin``) the driver
runs the same blocks and episode ends and leaves out the files: no loss logs, evaluations,
checkpoints or finish.
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from typing import Any, Protocol

import torch

from rrls.agents.boundary import StepBoundary
from rrls.agents.learner import check_runs_first, run_slice
from rrls.agents.run import Run, export_policies

#: the learner's losses are logged every this many env steps (TensorBoard and W&B)
LOSS_EVERY = 1000


@dataclass
class Advance:
    """What a collector reports for one block of steps: the episodes that ended, as
    ``(step offset, run, return, length)`` in step order (offset ``n - 1``: the block's last
    step), and the last update's losses (``{name: (K,) tensor}``; empty before the warm-up
    ends)."""

    ends: list[tuple[int, int, float, int]] = field(default_factory=list)
    losses: dict[str, torch.Tensor] = field(default_factory=dict)


class Collector(Protocol):
    """A way of collecting a group's experience, driven by ``drive``."""

    #: the most env steps one ``advance`` may take (a block also ends where the driver says)
    block: int

    def running(self) -> contextlib.AbstractContextManager[Any]:
        """The context the whole run is driven in (the twin's CUDA stream)."""
        ...

    def start(self, states: list[dict[str, Any] | None]) -> None:
        """Every run's first episode, or the episodes of their checkpoints (``states``)."""
        ...

    def advance(self, step: int, n: int) -> Advance:
        """Env steps ``step + 1 .. step + n``: act, step, store, update."""
        ...

    def next_episode(self, k: int, step: int) -> None:
        """Run ``k``'s episode ended at ``step`` and was recorded: begin its next one."""
        ...

    def state(self, k: int) -> dict[str, Any]:
        """Run ``k``'s part of a checkpoint besides the learner's state."""
        ...


@dataclass
class Driver:
    """The cadence of one group of runs at the same step (see the module's docstring).

    ``runs``: the group's run directories, or empty (no files: the library loop on the twin);
    ``metas``: what each run's exported policies record; ``step``: where the group starts;
    ``starts``: the random warm-up's length; ``on_episode(k, step, return)`` at every episode
    end; ``threads``: polled once a block (``rrls.agents.threads``); ``on_progress(step)`` every
    ``progress_every`` steps (0: never).
    """

    learner: Any
    collector: Collector
    group: int
    steps: int
    starts: int
    runs: list[Run] = field(default_factory=list)
    metas: list[dict[str, Any]] = field(default_factory=list)
    step: int = 0
    on_episode: Callable[[int, int, float], None] | None = None
    threads: Any = None
    on_progress: Callable[[int], None] | None = None
    progress_every: int = 0

    def run(self, states: list[dict[str, Any] | None]) -> None:
        """Drive the group from ``step`` to ``steps`` (``states``: the runs' checkpoints, None
        for a fresh start), then write each run's final files."""
        drive([self], [states])

    def finish(self) -> None:
        """Each run's exported policies and ``run.json``."""
        for k, run in enumerate(self.runs):
            summary = {"steps": run.step, "episodes": run.episodes}
            run.finish(export_policies(self.learner, k, self.metas[k]), summary)

    def _bar(self) -> contextlib.AbstractContextManager[Any]:
        if not self.runs:
            return contextlib.nullcontext(_NoBar())
        return _closing(self.runs[0].progress(self.group))

    def _block(self) -> int:
        """The next block's length: up to the collector's block, ending at every step the host
        must see (checkpoint, evaluation, loss log, progress point)."""
        step = self.step
        ends = [self.collector.block, self.steps - step]
        if self.runs:
            ends += [self.runs[0].steps_to_checkpoint(), LOSS_EVERY - step % LOSS_EVERY]
            ends += [n for n in (self.runs[0].steps_to_eval(),) if n]
        if self.progress_every:
            ends.append(self.progress_every - step % self.progress_every)
        return min(ends)

    def _advance(self, n: int) -> None:
        first = self.step
        out = self.collector.advance(first, n)
        last = [end for end in out.ends if end[0] == n - 1]
        for j, k, ret, length in out.ends:
            if j < n - 1:  # inside the block: nothing else happened at its step
                self._set_step(first + j + 1)
                self._episode_end(k, ret, length)
        self._set_step(first + n)
        if self.runs:
            if self.step > self.starts and self.step % LOSS_EVERY == 0 and out.losses:
                values = {name: v.cpu().tolist() for name, v in out.losses.items()}
                for k, run in enumerate(self.runs):
                    run.log({f"losses/{name}": v[k] for name, v in values.items()})
            if self.runs[0].eval_due():
                for k, run in enumerate(self.runs):
                    run.evaluate(export_policies(self.learner, k, self.metas[k])["policy"])
        for _, k, ret, length in last:
            self._episode_end(k, ret, length)
        if self.threads is not None:
            self.threads.poll()
        if self.runs and self.runs[0].checkpoint_due():
            self.checkpoint()
        if self.on_progress is not None and self.progress_every:
            if self.step % self.progress_every == 0:
                self.on_progress(self.step)

    def _set_step(self, step: int) -> None:
        self.step = step
        for run in self.runs:
            run.step = step

    def _episode_end(self, k: int, ret: float, length: int) -> None:
        """Run ``k``'s episode ended at this step: the learner's hook, the run's curves, the
        caller's hook, then the collector's next episode (no transition crosses it)."""
        extra = self.learner.episode_end(k, ret, length)
        if self.runs:
            self.runs[k].episode_end(ret, length, **extra)
        if self.on_episode is not None:
            self.on_episode(k, self.step, ret)
        self.collector.next_episode(k, self.step)

    def checkpoint(self, interrupted: bool = False) -> None:
        """Every run's checkpoint: its slice of the learner's state and the collector's part."""
        state = self.learner.state_dict()
        check_runs_first(state, self.group)  # a wrong layout: one line now, not at resume
        for k, run in enumerate(self.runs):
            run.save({"learner": run_slice(state, k), **self.collector.state(k)}, interrupted)


def drive(drivers: list[Driver], states: list[list[dict[str, Any] | None]]) -> None:
    """Drive groups in lockstep, every block of each at the same steps (``states``: each
    group's checkpoints): one group alone, or several algorithms' groups whose collectors share
    one twin step (``rrls.agents.resident.SharedBlocks``: the first group's ``advance`` steps
    them all). A block ends wherever one of them must look; each group keeps its own cadence's
    files, checkpoints included."""
    if len({(d.step, d.steps) for d in drivers}) != 1:
        raise ValueError("groups driven together start at the same step with the same budget")
    first = drivers[0]
    ctrl_c = StepBoundary()  # Ctrl-C: a checkpoint at the end of its block, then stop
    with contextlib.ExitStack() as stack:
        bars = [stack.enter_context(d._bar()) for d in drivers]
        for d in drivers:
            stack.enter_context(d.collector.running())
        for d, group_states in zip(drivers, states):
            d.collector.start(group_states)
        try:
            ctrl_c.hold()
            while first.step < first.steps:
                n = min(d._block() for d in drivers)
                for d, bar in zip(drivers, bars):
                    d._advance(n)
                    bar.update(d.group * n)
                for d in drivers:  # after every group's checkpoint at this step
                    if d.runs and d.runs[0].saved_step == d.step:
                        d.runs[0].check_stop()
                if ctrl_c.requested:  # Ctrl-C came during this block: keep its end, stop
                    for d in drivers:
                        if d.runs and d.runs[0].saved_step != d.step:
                            d.checkpoint(interrupted=True)
                    raise KeyboardInterrupt
        finally:
            ctrl_c.release()
    for d in drivers:
        d.finish()


class _NoBar:
    def update(self, n: int) -> None:
        pass


@contextlib.contextmanager
def _closing(bar: Any) -> Iterator[Any]:
    try:
        yield bar
    finally:
        bar.close()


__all__ = ["LOSS_EVERY", "Advance", "Collector", "Driver", "drive"]
