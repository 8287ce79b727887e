"""One seed, one stream per purpose: every generator of a run is a child of ``SeedSequence(seed)``.

A run asks for a stream by purpose (``"init"``, ``"noise"``, ``"replay"``, ``"explore"``,
``"warmup"``, ``"env"``, an algorithm's own names). The child for purpose ``p`` of run ``s`` is
``SeedSequence(s, spawn_key=(crc32(p),))`` — exactly what ``SeedSequence(s).spawn`` makes, keyed
by name instead of by position, so a third-party learner may ask for any purpose without
renumbering the others. Children with different keys or different seeds are independent streams
(NumPy's guarantee); ``tests/test_seeds.py`` checks that no two runs and no two purposes share
one. Why not ``seed, seed + 1, ...``: run ``s``'s second stream would be run ``s + 1``'s first.
"""

from __future__ import annotations

import json
import zlib

import numpy as np

from rrls.files import loads_json

__all__ = ["Generators", "NumpyGenerators", "RunSeeds", "rng_state", "set_rng_state"]

#: the purposes the loop and the built-in learners use (a learner may use others)
PURPOSES = ("env", "warmup", "explore", "init", "noise", "replay", "algo")


class RunSeeds:
    """The generators of one run, all spawned from ``SeedSequence(seed)``."""

    def __init__(self, seed: int) -> None:
        self.seed = int(seed)

    def sequence(self, purpose: str) -> np.random.SeedSequence:
        """The child ``SeedSequence`` of ``purpose``."""
        key = zlib.crc32(purpose.encode())
        return np.random.SeedSequence(self.seed, spawn_key=(key,))

    def numpy(self, purpose: str) -> np.random.Generator:
        """A numpy generator (PCG64) on ``purpose``'s stream."""
        return np.random.Generator(np.random.PCG64(self.sequence(purpose)))

    def integer(self, purpose: str) -> int:
        """A 63-bit integer from ``purpose``'s stream (``env.reset(seed=...)``, torch seeds)."""
        return int(self.sequence(purpose).generate_state(1, np.uint64)[0] >> np.uint64(1))

    def torch(self, purpose: str):  # torch is imported lazily (no torch for envs)
        """A CPU ``torch.Generator`` seeded from ``purpose``'s stream."""
        import torch

        return torch.Generator().manual_seed(self.integer(purpose))


class Generators:
    """The ``K`` runs' torch generators of one purpose, checkpointed as one ``(K, n)`` tensor."""

    def __init__(self, seeds: list[RunSeeds], purpose: str) -> None:
        self.list = [s.torch(purpose) for s in seeds]

    def __getitem__(self, k: int):
        return self.list[k]

    def __iter__(self):
        return iter(self.list)

    def __len__(self) -> int:
        return len(self.list)

    def state_dict(self):
        import torch

        return torch.stack([g.get_state() for g in self.list])

    def load_state_dict(self, state) -> None:
        for g, s in zip(self.list, state):
            g.set_state(s.clone())


class NumpyGenerators:
    """The ``K`` runs' numpy generators of one purpose (exploration noise, M2TD3's draws),
    checkpointed as one ``(K, 10)`` int64 tensor (PCG64's 128-bit state and increment as
    32-bit words, plus its cached half-word)."""

    def __init__(self, seeds: list[RunSeeds], purpose: str) -> None:
        self.list = [s.numpy(purpose) for s in seeds]

    def __getitem__(self, k: int) -> np.random.Generator:
        return self.list[k]

    def __iter__(self):
        return iter(self.list)

    def state_dict(self):
        import torch

        def words(x: int) -> list[int]:
            return [(x >> (32 * i)) & 0xFFFFFFFF for i in range(4)]

        rows = []
        for g in self.list:
            s = g.bit_generator.state
            rows.append(
                words(s["state"]["state"])
                + words(s["state"]["inc"])
                + [s["has_uint32"], s["uinteger"]]
            )
        return torch.tensor(rows, dtype=torch.int64)

    def load_state_dict(self, state) -> None:
        for g, row in zip(self.list, state.tolist()):

            def value(w: list[int]) -> int:
                return sum(int(x) << (32 * i) for i, x in enumerate(w))

            g.bit_generator.state = {
                "bit_generator": "PCG64",
                "state": {"state": value(row[:4]), "inc": value(row[4:8])},
                "has_uint32": int(row[8]),
                "uinteger": int(row[9]),
            }


def rng_state(gen: np.random.Generator) -> str:
    """A numpy generator's state as JSON (checkpoints keep it, so a resume draws on)."""
    return json.dumps(gen.bit_generator.state)


def set_rng_state(gen: np.random.Generator, state: str) -> None:
    gen.bit_generator.state = loads_json(state, "a checkpoint's generator state")
