"""The learner protocol: what an algorithm gives the training loop (``docs/algorithms.md``).

A learner holds a *group* of ``K`` runs (a run alone: ``K = 1``), which differ only in their
seeds. Six methods::

    __init__(env, config, seeds, device)   # seeds: one ``RunSeeds`` per run
    act(obs) -> list of K env actions      # exploring (the loop does the random warm-up)
    observe(obs, actions, rewards, next_obs, terminated, infos)   # store the K transitions
    update(step) -> {name: (K,) tensor}    # called every env step after the warm-up
    state_dict() / load_state_dict(state)  # everything, tensors with the runs first
    export(k) -> {"policy": MLPPolicy[, "adversary": MLPPolicy]}   # run k's final policies

Three optional hooks: ``episode_options(k, step)`` (``reset(options=...)``, M2TD3's ω),
``episode_end(k, ret, length) -> {scalar: value}`` and ``same_start`` (True: every episode is
reset with the run's first seed, one start state, as the M2TD3 authors' trainer).

The convention that lets the loop checkpoint each run on its own: in ``state_dict()``, every
tensor with at least one dimension has the run first (``(K, ...)``); 0-d tensors and plain
values are common to the group (step counts). A run's checkpoint is its slice ``[k : k + 1]`` of
every such tensor (a group of one), whatever group it was trained in.

The device-resident loop (``rrls.agents.on_twin``: the Warp twin's observations, the replay
and the updates stay on the GPU) calls four more methods, which TD3, DR, SAC and SAC-DR have::

    draw_ahead(steps) -> {name: (steps, ...) tensor}   # the next steps' random inputs
    act_tensor(obs, draws) -> (K, act) tensor          # draws: one step's row of each
    put(obs, actions, rewards, next_obs, terminated)   # observe, for device tensors
    update_drawn(step, draws) -> {name: (K,) tensor}   # update, on that step's row

Why ahead: each run draws from its own seeded generators on the CPU (so a run does not depend
on its group), and drawing a block of steps at once uploads them once per block instead of
once per step. Row ``t`` of every stream belongs to env step ``t``, used or not, so a run's
numbers do not depend on the block size.
"""

from __future__ import annotations

from typing import Any, Protocol, runtime_checkable

import numpy as np
import torch

__all__ = [
    "DeviceActing",
    "DeviceLearnerProtocol",
    "Learner",
    "LearnerProtocol",
    "StateLayoutError",
    "check_runs_first",
    "run_slice",
    "stack_runs",
]


@runtime_checkable
class LearnerProtocol(Protocol):
    """What the training loop calls on a learner (``K`` runs; see the module docstring).
    A class that has these methods is a learner; subclassing ``Learner`` adds the optional
    hooks' defaults."""

    def __init__(self, env: Any, config: Any, seeds: list[Any], device: torch.device) -> None: ...
    def act(self, obs: np.ndarray) -> list[Any]: ...
    def observe(self, obs, actions, rewards, next_obs, terminated, infos) -> None: ...
    def update(self, step: int) -> dict[str, torch.Tensor]: ...
    def state_dict(self) -> dict[str, Any]: ...
    def load_state_dict(self, state: dict[str, Any]) -> None: ...
    def export(self, k: int) -> dict[str, Any]: ...


@runtime_checkable
class DeviceLearnerProtocol(Protocol):
    """What the device-resident loop calls beyond ``LearnerProtocol`` (the module docstring)."""

    def draw_ahead(self, steps: int) -> dict[str, torch.Tensor]: ...
    def act_tensor(self, obs: torch.Tensor, draws: dict[str, torch.Tensor]) -> torch.Tensor: ...
    def put(self, obs, actions, rewards, next_obs, terminated) -> None: ...
    def update_drawn(self, step: int, draws: dict[str, torch.Tensor]) -> dict: ...


class DeviceActing:
    """``act_tensor`` and ``put`` for a learner with a ``buffer`` (``ReplayBuffer``), an
    ``_update`` (``graphs.Update``) and ``_act_on_device(variant, {"obs", "noise"})``: acting is
    an ``Update`` made as the learner's update was (compiled, captured), on first use."""

    _act: Any = None

    def act_tensor(self, obs: torch.Tensor, draws: dict[str, torch.Tensor]) -> torch.Tensor:
        """``act`` on the device, ``(K, obs) -> (K, act)``, with that step's ``noise``."""
        if self._act is None:
            self._act = self._update.sibling(self._act_on_device)  # type: ignore[attr-defined]
        return self._act(None, {"obs": obs, "noise": draws["noise"]})

    def put(self, obs, actions, rewards, next_obs, terminated) -> None:
        """``observe`` for device tensors."""
        self.buffer.put(  # type: ignore[attr-defined]
            obs=obs, action=actions, reward=rewards, next_obs=next_obs, terminated=terminated
        )


class Learner:
    """Base class: the six methods to write, and the optional hooks' defaults (subclassing it is
    not required; ``LearnerProtocol`` is what is checked)."""

    def act(self, obs: np.ndarray) -> list[Any]:
        raise NotImplementedError

    def observe(self, obs, actions, rewards, next_obs, terminated, infos) -> None:
        raise NotImplementedError

    def update(self, step: int) -> dict[str, torch.Tensor]:
        raise NotImplementedError

    def state_dict(self) -> dict[str, Any]:
        raise NotImplementedError

    def load_state_dict(self, state: dict[str, Any]) -> None:
        raise NotImplementedError

    def export(self, k: int) -> dict[str, Any]:
        raise NotImplementedError

    same_start = False  # True: every reset reuses the run's first seed (one start state)

    def episode_options(self, k: int, step: int) -> dict | None:
        return None

    def episode_end(self, k: int, episode_return: float, length: int) -> dict[str, float]:
        return {}


class StateLayoutError(ValueError):
    """A learner's ``state_dict`` does not have the runs first (raised at the first checkpoint,
    before a resume would find a wrong slice)."""


def check_runs_first(state: Any, runs: int, path: str = "state") -> None:
    """Refuse, naming the tensor, a state whose tensors of dimension >= 1 do not have ``runs``
    rows first: a plain ``nn.Linear`` of one run has ``weight`` of shape ``(out, in)``, whose
    ``[k : k + 1]`` slice would checkpoint one output row and fail only at resume."""
    if isinstance(state, torch.Tensor):
        if state.dim() and state.shape[0] != runs:
            raise StateLayoutError(
                f"learner state {path} has shape {tuple(state.shape)}: every tensor of "
                f"dimension >= 1 must have the runs first, ({runs}, ...) for this group of "
                f"{runs} (keep 0-d tensors for values common to the group; docs/algorithms.md)"
            )
    elif isinstance(state, dict):
        for key, value in state.items():
            check_runs_first(value, runs, f"{path}[{key!r}]")
    elif isinstance(state, list | tuple):
        for i, value in enumerate(state):
            check_runs_first(value, runs, f"{path}[{i}]")


def run_slice(state: Any, k: int) -> Any:
    """Run ``k``'s part of a group's state (every tensor of dimension >= 1 is runs-first)."""
    if isinstance(state, torch.Tensor):
        return (state[k : k + 1] if state.dim() else state).detach().cpu().clone()
    if isinstance(state, dict):
        return {key: run_slice(v, k) for key, v in state.items()}
    if isinstance(state, list | tuple):
        return type(state)(run_slice(v, k) for v in state)
    return state


def stack_runs(states: list[Any]) -> Any:
    """The group state of runs' ``run_slice`` states (the inverse of ``run_slice``)."""
    first = states[0]
    if isinstance(first, torch.Tensor):
        return torch.cat(states) if first.dim() else first
    if isinstance(first, dict):
        return {key: stack_runs([s[key] for s in states]) for key in first}
    if isinstance(first, list | tuple):
        return type(first)(stack_runs(list(parts)) for parts in zip(*states))
    return first
