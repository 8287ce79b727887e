"""Actor and twin critic of the paper (Appendix, "Actor/Critic architecture"): 256-256 MLPs.

The two critics live in one module with stacked weights, so each layer of both is a single
batched matmul (``torch.baddbmm``) instead of two small ones — the same mathematics as two
separate ``nn.Linear`` stacks, initialised the same way (PyTorch's Linear default).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
import torch
from torch import nn


class Actor(nn.Module):
    """Deterministic policy: ReLU hidden layers, tanh output scaled to the action box."""

    def __init__(
        self,
        obs_dim: int,
        act_dim: int,
        hidden: Sequence[int] = (256, 256),
        action_low: np.ndarray | float = -1.0,
        action_high: np.ndarray | float = 1.0,
    ) -> None:
        super().__init__()
        sizes = [obs_dim, *hidden, act_dim]
        self.layers = nn.ModuleList(nn.Linear(a, b) for a, b in zip(sizes[:-1], sizes[1:]))
        low = torch.tensor(np.broadcast_to(action_low, (act_dim,)), dtype=torch.float32)
        high = torch.tensor(np.broadcast_to(action_high, (act_dim,)), dtype=torch.float32)
        self.register_buffer("action_scale", (high - low) / 2)
        self.register_buffer("action_bias", (high + low) / 2)

    def forward(self, obs: torch.Tensor) -> torch.Tensor:
        h = obs
        for layer in self.layers[:-1]:
            h = torch.relu(layer(h))
        return torch.tanh(self.layers[-1](h)) * self.action_scale + self.action_bias

    def to_mlp_policy(self, metadata: dict | None = None):  # noqa: ANN201 - avoids a cycle
        """The same actor as a numpy ``MLPPolicy`` (the safe ``.npz`` read by ``rrls evaluate``)."""
        from rrls.evaluation.policies import MLPPolicy

        weights = [layer.weight.detach().cpu().numpy().T for layer in self.layers]
        biases = [layer.bias.detach().cpu().numpy() for layer in self.layers]
        return MLPPolicy(
            weights,
            biases,
            self.action_scale.cpu().numpy(),
            self.action_bias.cpu().numpy(),
            metadata=metadata,
        )


class TwinCritic(nn.Module):
    """``n`` Q-networks Q(x) over the same input, evaluated together: output ``(n, B)``."""

    def __init__(self, in_dim: int, hidden: Sequence[int] = (256, 256), n: int = 2) -> None:
        super().__init__()
        sizes = [in_dim, *hidden, 1]
        self.weights = nn.ParameterList()
        self.biases = nn.ParameterList()
        for fan_in, fan_out in zip(sizes[:-1], sizes[1:]):
            bound = 1 / math.sqrt(fan_in)  # nn.Linear's default init, per critic
            self.weights.append(
                nn.Parameter(torch.empty(n, fan_in, fan_out).uniform_(-bound, bound))
            )
            self.biases.append(nn.Parameter(torch.empty(n, 1, fan_out).uniform_(-bound, bound)))
        self.n = n

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        h = x.unsqueeze(0).expand(self.n, *x.shape)
        last = len(self.weights) - 1
        for i, (w, b) in enumerate(zip(self.weights, self.biases)):
            h = torch.baddbmm(b, h, w)
            if i < last:
                h = torch.relu(h)
        return h.squeeze(-1)

    def q1(self, x: torch.Tensor) -> torch.Tensor:
        """The first critic only (TD3's actor loss): half the work of ``forward``."""
        h = x
        last = len(self.weights) - 1
        for i, (w, b) in enumerate(zip(self.weights, self.biases)):
            h = torch.addmm(b[0], h, w[0])
            if i < last:
                h = torch.relu(h)
        return h.squeeze(-1)
