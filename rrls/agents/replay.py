"""A preallocated tensor replay for a group of runs (no Python objects per transition).

The ``K`` runs of a group step in lockstep, so their buffers fill together: one ``(K, rows,
width)`` table with a shared write position, each run's rows its own, each field a block of
columns (a batch is one gather). Sampling draws each run's indices from its own ``"replay"``
generator on the CPU, whatever the device, so a run samples the same batches alone or in any
group, and a resumed run the same as an uninterrupted one. The capacity is ``buffer_size``
whatever ``--steps`` (extending a finished run with ``--resume --steps N`` then equals the
N-step run); on a CPU the table grows by doubling as it fills, on a GPU it is allocated at once
(a captured CUDA graph keeps its address).

The device-resident loop (``rrls.agents.on_twin``) stores device tensors with ``put`` and draws
a block of steps' indices at once with ``draw_ahead``: uniform numbers from each run's own
``"replay.ahead"`` numpy stream, scaled on the host by the size the buffer will have at each of
those steps, uploaded once per block. Row ``t`` of that stream belongs to env step ``t`` whether
an update uses it or not, so a run's batches do not depend on the block size.
"""

from __future__ import annotations

import math

import numpy as np
import torch

from rrls.agents.streams import Generators, NumpyGenerators, RunSeeds

__all__ = [
    "ReplayBuffer",
    "transition_fields",
]


def transition_fields(
    obs_dim: int, act_shape: tuple[int, ...], **extra: tuple[int, ...]
) -> dict[str, tuple[int, ...]]:
    """The fields of a transition (plus ``extra`` ones, e.g. M2TD3's ω) for ``ReplayBuffer``."""
    return {
        "obs": (obs_dim,),
        "action": tuple(act_shape),
        "reward": (),
        "next_obs": (obs_dim,),
        "terminated": (),
        **extra,
    }


class ReplayBuffer:
    """Circular buffers of ``len(seeds)`` runs; ``fields`` maps a name to its per-transition
    shape; ``gather`` returns fields shaped ``(K, batch, *shape)``."""

    def __init__(
        self,
        capacity: int,
        fields: dict[str, tuple[int, ...]],
        device: torch.device | str,
        seeds: list[RunSeeds],
        purpose: str = "replay",
    ) -> None:
        self.capacity, self.group = int(capacity), len(seeds)
        self.device = torch.device(device)
        self.shapes = {name: tuple(shape) for name, shape in fields.items()}
        self._widths = [math.prod(shape) for shape in self.shapes.values()]
        self.width = sum(self._widths)
        rows = self.capacity if self.device.type == "cuda" else min(self.capacity, 4096)
        self._allocate(rows)
        self._row = np.zeros((self.group, self.width), dtype=np.float32)  # the step being written
        self._columns: dict[str, np.ndarray] = {}
        start = 0
        for name, width in zip(self.shapes, self._widths):
            self._columns[name] = self._row[:, start : start + width]
            start += width
        self.pos = self.size = 0
        self.generators = Generators(seeds, purpose)
        self.seeds, self.purpose = seeds, purpose
        self.ahead: NumpyGenerators | None = None  # draw_ahead's streams, made on first use

    def _allocate(self, rows: int) -> None:
        table = torch.zeros((self.group, rows, self.width), device=self.device)
        if hasattr(self, "table"):
            table[:, : self.table.shape[1]] = self.table
        self.table = table
        self._flat = table.view(-1, self.width)
        self._offsets = torch.arange(self.group, device=self.device).unsqueeze(1) * rows

    def add(self, **transitions: np.ndarray) -> None:
        """Store one transition per run: each field ``(K, *shape)`` (or ``(K,)`` for scalars)."""
        for name, value in transitions.items():
            self._columns[name][:] = np.asarray(value, dtype=np.float32).reshape(self.group, -1)
        self._write(torch.from_numpy(self._row))

    def put(self, **transitions: torch.Tensor) -> None:
        """``add`` for tensors already on the device (every field, each ``(K, *shape)``): one
        copy into the table, no trip through the host."""
        missing = set(self.shapes) ^ set(transitions)
        if missing:
            raise ValueError(f"put: fields {sorted(missing)} differ from {list(self.shapes)}")
        row = torch.cat(
            [transitions[name].reshape(self.group, -1).float() for name in self.shapes], 1
        )
        self._write(row)

    def _write(self, row: torch.Tensor) -> None:
        """Row ``(K, width)`` at the write position (the table grows first if it is full)."""
        if self.pos >= self.table.shape[1]:
            self._allocate(min(self.capacity, 2 * self.table.shape[1]))
        self.table[:, self.pos].copy_(row)
        self.pos = (self.pos + 1) % self.capacity
        self.size = min(self.size + 1, self.capacity)

    def draw_ahead(self, steps: int, batch_size: int) -> torch.Tensor:
        """The batch indices of the next ``steps`` env steps, ``(steps, K, batch)`` on the
        device: step ``j`` (``0``-based) samples the ``min(size + j + 1, capacity)`` rows the
        buffer will hold once that step's transition is stored."""
        if self.ahead is None:
            self.ahead = NumpyGenerators(self.seeds, self.purpose + ".ahead")
        u = np.stack([rng.random((steps, batch_size)) for rng in self.ahead], 1)
        sizes = np.minimum(self.size + 1 + np.arange(steps), self.capacity)
        idx = (u * sizes[:, None, None]).astype(np.int64)
        return torch.from_numpy(idx).to(self.device)

    def draw(self, batch_size: int) -> torch.Tensor:
        """Each run's batch indices from its own generator, ``(K, batch)``, on the CPU."""
        return torch.stack(
            [torch.randint(0, self.size, (batch_size,), generator=g) for g in self.generators]
        )

    def gather(self, idx: torch.Tensor) -> dict[str, torch.Tensor]:
        """The rows ``idx`` (``(K, batch)``) of each run's buffer, as one view per field."""
        k, batch = idx.shape
        rows = self._flat.index_select(0, (idx + self._offsets[:k]).view(-1)).view(k, batch, -1)
        fields = {}
        for (name, shape), block in zip(self.shapes.items(), rows.split(self._widths, 2)):
            fields[name] = block.squeeze(2) if not shape else block.view(k, batch, *shape)
        return fields

    def __len__(self) -> int:
        return self.size

    def state_dict(self) -> dict[str, object]:
        """The filled rows (runs first), the position and the sampling generators."""
        return {
            "table": self.table[:, : self.size].clone(),
            "pos": self.pos,
            "size": self.size,
            "generator": self.generators.state_dict(),
            # draw_ahead's streams, once used (the device-resident loop's checkpoints)
            **({"ahead": self.ahead.state_dict()} if self.ahead is not None else {}),
        }

    def load_state_dict(self, state: dict[str, object]) -> None:
        self.pos, self.size = int(state["pos"]), int(state["size"])
        if self.table.shape[1] < self.size:
            self._allocate(min(self.capacity, 1 << max(0, self.size - 1).bit_length()))
        self.table[:, : self.size] = state["table"].to(self.device)
        self.generators.load_state_dict(state["generator"])
        if "ahead" in state:
            self.ahead = NumpyGenerators(self.seeds, self.purpose + ".ahead")
            self.ahead.load_state_dict(state["ahead"])
