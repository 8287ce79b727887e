"""A preallocated tensor replay, one per run of a group (no Python objects per transition).

The ``K`` runs of a group step in lockstep, so their buffers fill together: one ``(K, capacity,
width)`` table with a shared write position, each run's rows its own. A step's ``K`` transitions
are one row write (one host-to-device copy on a GPU). Sampling draws each run's indices from its
own seeded ``torch.Generator`` (on the CPU, whatever the device; checkpointed), so a run samples
the same batches alone or in any group, and a resumed run the same as an uninterrupted one.
"""

from __future__ import annotations

import math

import numpy as np
import torch


def transition_fields(
    obs_dim: int, act_shape: tuple[int, ...], **extra: tuple[int, ...]
) -> dict[str, tuple[int, ...]]:
    """The fields of a TD3 transition (plus ``extra`` ones, e.g. M2TD3's ω) for ``ReplayBuffer``."""
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
    shape. ``sample`` returns fields shaped ``(K, batch, *shape)``."""

    def __init__(
        self,
        capacity: int,
        fields: dict[str, tuple[int, ...]],
        device: torch.device | str = "cpu",
        seeds: list[int] | int = 0,
    ) -> None:
        seeds = [seeds] if isinstance(seeds, int) else list(seeds)
        self.capacity, self.group = int(capacity), len(seeds)
        self.device = torch.device(device)
        # one table, each field a block of its columns: a batch is a single gather (one instead
        # of one per field), fields are views of it
        self.shapes = {name: tuple(shape) for name, shape in fields.items()}
        self._widths = [math.prod(shape) for shape in self.shapes.values()]
        self.width = sum(self._widths)
        self.table = torch.zeros(
            (self.group, self.capacity, self.width), dtype=torch.float32, device=self.device
        )
        self._flat = self.table.view(self.group * self.capacity, self.width)
        self._offsets = torch.arange(self.group, device=self.device).unsqueeze(1) * self.capacity
        self._row = np.zeros((self.group, self.width), dtype=np.float32)  # the step being written
        self._columns: dict[str, np.ndarray] = {}
        start = 0
        for name, width in zip(self.shapes, self._widths):
            self._columns[name] = self._row[:, start : start + width]
            start += width
        self.pos = 0
        self.size = 0
        self.generators = [torch.Generator(device="cpu").manual_seed(s) for s in seeds]

    def add(self, **transitions: np.ndarray) -> None:
        """Store one transition per run: each field ``(K, *shape)`` (or ``(K,)`` for scalars)."""
        for name, value in transitions.items():
            self._columns[name][:] = np.asarray(value, dtype=np.float32).reshape(self.group, -1)
        if self.device.type == "cpu":
            self.table[:, self.pos].copy_(torch.from_numpy(self._row))
        else:
            self.table[:, self.pos].copy_(torch.from_numpy(self._row).to(self.device))
        self.pos = (self.pos + 1) % self.capacity
        self.size = min(self.size + 1, self.capacity)

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

    def sample(self, batch_size: int) -> dict[str, torch.Tensor]:
        return self.gather(self.draw(batch_size).to(self.device))

    def __len__(self) -> int:
        return self.size

    # -- per-run checkpoints ----------------------------------------------------------------
    def state(self, k: int) -> dict[str, object]:
        """Run ``k``'s filled rows, position and sampling generator."""
        return {
            "table": self.table[k, : self.size].cpu().clone(),
            "pos": self.pos,
            "size": self.size,
            "generator": self.generators[k].get_state(),
        }

    def load(self, k: int, state: dict[str, object]) -> None:
        pos, size = int(state["pos"]), int(state["size"])
        if k and (pos, size) != (self.pos, self.size):
            raise ValueError("the runs of a group must resume from the same step")
        self.pos, self.size = pos, size
        self.table[k, : self.size] = state["table"].to(self.device)
        self.generators[k].set_state(state["generator"])
