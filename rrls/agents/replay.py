"""A preallocated tensor replay buffer (no Python objects per transition, no numpy↔torch per batch).

Sampling draws indices from a seeded ``torch.Generator`` whose state is checkpointed, so a resumed
run samples exactly the batches an uninterrupted run would.
"""

from __future__ import annotations

import math

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
    """Circular buffer of transitions; ``fields`` maps a name to its per-transition shape."""

    def __init__(
        self,
        capacity: int,
        fields: dict[str, tuple[int, ...]],
        device: torch.device | str = "cpu",
        seed: int = 0,
    ) -> None:
        self.capacity = int(capacity)
        self.device = torch.device(device)
        # one (capacity, width) table, each field a block of its columns: a batch is a single
        # index_select (one gather instead of one per field), fields are views of it
        self.shapes = {name: tuple(shape) for name, shape in fields.items()}
        self._widths = [math.prod(shape) for shape in self.shapes.values()]
        self.table = torch.zeros(
            (self.capacity, sum(self._widths)), dtype=torch.float32, device=self.device
        )
        self.data = self._split(self.table)
        # on CPU, write through numpy views of the same memory: ~1 µs per field instead of ~5
        self._views = (
            {name: t.numpy() for name, t in self.data.items()}
            if self.device.type == "cpu"
            else None
        )
        self.pos = 0
        self.size = 0
        self.generator = torch.Generator(device="cpu").manual_seed(seed)

    def _split(self, rows: torch.Tensor) -> dict[str, torch.Tensor]:
        """Rows of the table as one view per field: one ``split`` into column blocks (~8 µs for a
        TD3 batch, against ~19 for a slice and a view per field); scalars lose their column,
        other shapes are restored by a view."""
        fields = {}
        for (name, shape), block in zip(self.shapes.items(), rows.split(self._widths, 1)):
            if not shape:
                block = block.squeeze(1)
            elif len(shape) > 1:
                block = block.view(len(rows), *shape)
            fields[name] = block
        return fields

    def add(self, **transition: object) -> None:
        """Store one transition (arrays or floats, one per field)."""
        if self._views is not None:
            for name, value in transition.items():
                self._views[name][self.pos] = value
        else:
            for name, value in transition.items():
                self.data[name][self.pos] = torch.as_tensor(value, dtype=torch.float32)
        self.pos = (self.pos + 1) % self.capacity
        self.size = min(self.size + 1, self.capacity)

    def sample(self, batch_size: int) -> dict[str, torch.Tensor]:
        idx = torch.randint(0, self.size, (batch_size,), generator=self.generator)
        return self._split(self.table.index_select(0, idx.to(self.device)))

    def __len__(self) -> int:
        return self.size

    # -- checkpoints ------------------------------------------------------------------------
    def state_dict(self) -> dict[str, object]:
        """Only the filled part of the buffer, plus the sampling generator."""
        return {
            "data": {name: values[: self.size].cpu().clone() for name, values in self.data.items()},
            "pos": self.pos,
            "size": self.size,
            "generator": self.generator.get_state(),
        }

    def load_state_dict(self, state: dict[str, object]) -> None:
        self.pos, self.size = int(state["pos"]), int(state["size"])
        for name, values in state["data"].items():
            self.data[name][: self.size] = values.to(self.device)
        self.generator.set_state(state["generator"])
