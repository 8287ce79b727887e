"""How a worst case is rechecked (``rrls.evaluation.recheck``): settings a ``Protocol`` holds,
in a module of their own so that the protocol needs nothing of the evaluation to hold them."""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

__all__ = ["Recheck"]


@dataclass(frozen=True)
class Recheck:
    """How the worst case is rechecked (``rrls.evaluation.recheck``): the ``worst`` lowest
    points, ``episodes`` fresh episodes each, and the ``quantile`` of the point means reported
    beside it."""

    worst: int = 10
    episodes: int = 20
    quantile: float = 0.05

    def __post_init__(self) -> None:
        for name in ("worst", "episodes"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
                raise ValueError(f"recheck {name} must be an integer >= 1, got {value!r}")
            if value > 100_000:
                raise ValueError(f"recheck {name} must be at most 100,000, got {value!r}")
        q = self.quantile
        if isinstance(q, bool) or not isinstance(q, (int, float)) or not 0 <= q <= 1:
            raise ValueError(f"recheck quantile must be a number in [0, 1], got {q!r}")

    def to_json(self) -> dict[str, Any]:
        return asdict(self)

    @classmethod
    def from_json(cls, data: Any) -> Recheck:
        if not isinstance(data, dict) or set(data) - {"worst", "episodes", "quantile"}:
            raise ValueError(
                f"recheck must be an object of worst, episodes, quantile: {data!r:.80}"
            )
        return cls(**data)
