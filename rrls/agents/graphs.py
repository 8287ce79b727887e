"""One code path for every learner's update: eager, compiled (``torch.compile``), and on a GPU
replayed from CUDA graphs.

An update of small networks is hundreds of tiny operations, each paying Python, dispatch and
autograd bookkeeping. LeanRL's recipe, in plain PyTorch:

- **compile** (``--compile``): ``torch.compile`` takes the whole update function — losses,
  ``backward`` and ``torch.optim.Adam.step`` — and inductor fuses it into C++ (CPU) or Triton
  (GPU) kernels. Torch itself splits it into a few graphs: at ``backward`` (dynamo does not
  trace it; the backward is compiled with the forward by AOTAutograd) and around
  ``Optimizer.step`` (a deliberate graph break of ``torch.optim``; the fused CPU Adam runs
  as its one kernel). Nothing of rrls's breaks a graph (``descend`` clears gradients in a way
  dynamo traces; ``Optimizer.zero_grad`` would not be). Each variant of an update (an actor
  step or not, whose player) compiles once, guarded on the variant; the CPU replay table's
  first growth recompiles once with its length dynamic. ``mode=None``, and on a GPU the
  compiled function is captured by ``Update`` itself (LeanRL's ``CudaGraphModule`` pattern),
  not inductor's ``reduce-overhead`` CUDA-graph trees, so both paths share one capture.
- **CUDA graphs** (``--cuda-graphs``, a GPU only): each variant is captured once in a
  ``torch.cuda.graph`` (after warm-up calls on a side stream, as PyTorch requires; the warm-up
  also compiles) and replayed: one launch per update. What makes that possible: the update is
  a function of its random inputs (replay indices, noise drawn on the CPU from each run's
  generators), which are copied into static tensors the graph reads, and the optimisers are
  ``torch.optim.Adam(capturable=True)`` (their step counts live on the GPU). If capture fails
  the update stays uncaptured, with a warning.
- **rehearsal** (``settings(rehearse=True)``, for tests on a CPU): everything the CUDA-graph
  path does — static input tensors per variant, copying the inputs in, reading the outputs the
  last call left — except the capture: the function is called instead of replayed. So the CPU
  suite runs every line of the GPU path but ``torch.cuda.graph`` itself.

Compiled code is cached on disk (``TORCHINDUCTOR_CACHE_DIR``; ``cache_dir``): the first
compile on a machine costs ~35 s for TD3 on a CPU, later runs and resumes ~4 s.
"""

from __future__ import annotations

import os
import warnings
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from contextvars import ContextVar
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import torch


@dataclass(frozen=True)
class Settings:
    """How the ``Update`` objects made under ``settings(...)`` run, read when each is made:
    the loop sets them around building a learner, so algorithm files need not pass them on."""

    graphs: bool = True  # --cuda-graphs / --no-cuda-graphs
    compile: bool = False  # --compile / --no-compile, resolved
    rehearse: bool = False  # everything the CUDA-graph path does but the capture (tests)


DEFAULTS = Settings()
_SETTINGS: ContextVar[Settings] = ContextVar("rrls_update_settings", default=DEFAULTS)


def current() -> Settings:
    """The settings an ``Update`` made now would read."""
    return _SETTINGS.get()


@contextmanager
def settings(**changes: bool) -> Iterator[Settings]:
    """``with settings(compile=True): learner = Learner(...)``: the changes hold inside the block
    (this thread or task only) and are undone after it, whatever happens there."""
    token = _SETTINGS.set(replace(_SETTINGS.get(), **changes))
    try:
        yield _SETTINGS.get()
    finally:
        _SETTINGS.reset(token)


#: Adam's options that depend on the device (``adam``), kept across ``load_optimizer``
DEVICE_FLAGS = ("capturable", "fused", "foreach")
#: the user's ``TORCHINDUCTOR_CACHE_DIR``, read before torch sets it: importing
#: dynamo (which the first optimiser does) writes inductor's default into it
USER_CACHE_DIR = os.environ.get("TORCHINDUCTOR_CACHE_DIR") or None


def cache_dir() -> Path:
    """Where inductor keeps compiled kernels, set for this process: ``TORCHINDUCTOR_CACHE_DIR``
    if the user set it (before starting Python), else ``$XDG_CACHE_HOME/rrls/inductor``
    (``~/.cache/rrls/inductor``).

    Why: inductor's default lives under ``/tmp/torchinductor_<user>``, which a reboot or a
    container restart empties; a stable per-user directory pays the compile once per machine
    (and torch version), and every later run and resume of the same shapes reuses it.
    """
    path = USER_CACHE_DIR
    if path is None:
        base = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache")
        path = str(base / "rrls" / "inductor")
    os.environ["TORCHINDUCTOR_CACHE_DIR"] = path
    return Path(path)


class Update:
    """``fn(variant, inputs)``: eagerly or compiled, and on a GPU replayed from a CUDA graph
    per ``variant`` (``inputs``: CPU tensors of fixed shapes per variant)."""

    def __init__(
        self,
        fn: Callable,
        device: torch.device | str,
        graphs: bool | None = None,
        compile: bool | None = None,  # the option's name
        rehearse: bool | None = None,
        warmup: int = 3,
    ) -> None:
        self.device, self.warmup = torch.device(device), warmup
        now = current()
        self.compiled = now.compile if compile is None else compile
        if self.compiled:
            cache_dir()
            fn = torch.compile(fn)
        self.fn = fn
        self.graphs = (now.graphs if graphs is None else graphs) and self.device.type == "cuda"
        self.static = self.graphs or (now.rehearse if rehearse is None else rehearse)
        self._entries: dict[Any, dict[str, Any]] = {}
        self._pool: Any = None

    def sibling(self, fn: Callable) -> Update:
        """An ``Update`` of ``fn`` made as this one was (compiled, captured, rehearsed), whatever
        the settings in force now: a learner's acting on the device, made on first use."""
        return Update(fn, self.device, self.graphs, self.compiled, self.static, self.warmup)

    def __call__(self, variant: Any, inputs: dict[str, torch.Tensor]) -> dict[str, torch.Tensor]:
        if not self.static:
            return self.fn(variant, {k: v.to(self.device) for k, v in inputs.items()})
        entry = self._entries.get(variant)
        if entry is None:
            static = {k: torch.empty_like(v, device=self.device) for k, v in inputs.items()}
            entry = self._entries[variant] = {"inputs": static, "calls": 0, "graph": None}
        for name, value in inputs.items():
            entry["inputs"][name].copy_(value, non_blocking=True)
        if not self.graphs:  # rehearsal: what a replay reads and writes, by a call
            return self.fn(variant, entry["inputs"])
        if entry["graph"] is not None:
            entry["graph"].replay()
            return entry["outputs"]
        if entry["calls"] < self.warmup:
            entry["calls"] += 1
            side = torch.cuda.Stream(self.device)
            side.wait_stream(torch.cuda.current_stream(self.device))
            with torch.cuda.stream(side):
                out = self.fn(variant, entry["inputs"])
            torch.cuda.current_stream(self.device).wait_stream(side)
            return out
        return self._capture(entry, variant)

    def _capture(self, entry: dict[str, Any], variant: Any) -> dict[str, torch.Tensor]:
        graph = torch.cuda.CUDAGraph()
        try:
            with torch.cuda.graph(graph, pool=self._pool):
                outputs = self.fn(variant, entry["inputs"])
        except Exception as err:  # noqa: BLE001 - any capture failure: stay uncaptured
            message = f"CUDA graph capture failed ({err}); updates run uncaptured"
            warnings.warn(message, stacklevel=3)
            self.graphs = False
            return self.fn(variant, entry["inputs"])
        self._pool = graph.pool()
        entry["graph"], entry["outputs"] = graph, outputs
        graph.replay()
        return outputs


def adam(params, lr: float, device: torch.device, weight_decay: float = 0.0) -> torch.optim.Adam:
    """``torch.optim.Adam``: capturable on a GPU (its step count stays on the device, for CUDA
    graphs); fused on a CPU (one kernel for all parameters: measured ~10 % more updates/s at
    the paper's sizes than the default multi-tensor path). Both keep the same state.
    ``weight_decay``: Adam's L2 term (added to the gradient elementwise, so runs stay apart)."""
    cuda = torch.device(device).type == "cuda"
    if cuda:
        return torch.optim.Adam(params, lr=lr, capturable=True, weight_decay=weight_decay)
    return torch.optim.Adam(params, lr=lr, fused=True, weight_decay=weight_decay)


def load_optimizer(opt: torch.optim.Optimizer, state: dict[str, Any]) -> None:
    """``opt.load_state_dict(state)``, keeping ``opt``'s device options (``adam``).

    Why: ``torch.optim`` restores the saved groups' options too, so a checkpoint written on a
    GPU (``capturable=True``) would make a CPU optimiser refuse to step, and one written on a
    CPU (``fused``) would leave a GPU optimiser's step counts wherever the file had them. The
    state itself (moments, step counts) is the same on both; only where the counts live differs.
    """
    flags = [{k: group[k] for k in DEVICE_FLAGS if k in group} for group in opt.param_groups]
    opt.load_state_dict(state)
    for group, own in zip(opt.param_groups, flags):
        group.update(own)
        on_device = group.get("capturable") or group.get("fused")
        for p in group["params"]:
            step = opt.state.get(p, {}).get("step")
            if isinstance(step, torch.Tensor):
                where = p.device if on_device else torch.device("cpu")
                opt.state[p]["step"] = step.to(dtype=torch.float32, device=where)


def descend(opt: torch.optim.Optimizer, loss: torch.Tensor, only: bool = False) -> None:
    """One step of ``opt`` on ``loss.sum()`` (the runs' losses: each run's gradient is its own).

    ``only``: gradients into ``opt``'s parameters alone (an actor's loss also reaches the
    critic). The gradients are cleared by hand, as ``zero_grad()`` does: ``torch.compile``
    does not trace ``Optimizer.zero_grad`` (a graph break), it does trace this.
    """
    params = [p for group in opt.param_groups for p in group["params"]]
    for p in params:
        p.grad = None
    loss.sum().backward(inputs=params if only else None)
    opt.step()
