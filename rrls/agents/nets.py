"""The paper's networks (Appendix, "Actor/Critic architecture": 256-256 ReLU MLPs) for a group
of ``K`` runs at once, as ordinary ``nn.Module``s trained by autograd and ``torch.optim``.

Batched modules: every parameter has a leading run dimension (a run alone is ``K = 1``) and a
layer is one ``torch.baddbmm`` for all runs. Why: K small runs in one process pay each
operation's dispatch once, share the cores without oversubscribing them, and on a GPU fill it.
Runs never mix: the loss of a group is the sum of the runs' losses, so each run's gradient is
its own. A run's numbers alone and in a group agree to float32 rounding (the batched kernels may
order a sum differently; ``tests/test_group.py`` measures it at the paper's shapes).

Initialisation is ``nn.Linear``'s default (uniform in ``±1/sqrt(fan_in)``), drawn per run from
the run's own ``"init"`` generator, so a run's initial weights do not depend on its group.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
import torch
from torch import nn

__all__ = [
    "Actor",
    "Critic",
    "GaussianActor",
    "Linear",
    "NumpyActor",
    "deterministic",
    "mlp",
    "polyak",
    "relu_mlp",
    "to_mlp_policy",
]


class Linear(nn.Module):
    """Independent linear layers, one per run: ``(K, B, fan_in) -> (K, B, fan_out)``.

    With ``copies`` (a twin critic: 2), parameters are ``(K, copies, ...)`` (the run first,
    as checkpoints want) and inputs ``(K·copies, B, fan_in)``, entry ``k·copies + j``.
    """

    def __init__(
        self, fan_in: int, fan_out: int, gens: Sequence[torch.Generator], copies: int | None = None
    ) -> None:
        super().__init__()
        bound = 1 / math.sqrt(fan_in)

        def draw(*shape: int) -> list[torch.Tensor]:
            return [
                torch.empty(copies or 1, *shape).uniform_(-bound, bound, generator=g) for g in gens
            ]

        stack = torch.cat if copies is None else torch.stack
        self.weight = nn.Parameter(stack(draw(fan_in, fan_out)))
        self.bias = nn.Parameter(stack(draw(1, fan_out)))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        if self.weight.dim() == 4:
            return torch.baddbmm(self.bias.flatten(0, 1), x, self.weight.flatten(0, 1))
        if self.weight.shape[0] == 1 and self.weight.shape[-1] == 1:
            # A lone run's one-output layer: torch computes a batch of one [B, n] @ [n, 1] as a
            # matrix-vector product, whose sum order differs from the batched kernel's on some
            # CPUs (measured, AVX2: 1.7e-5 at n = 256, then 2.1e-4 in the weights after 1 000
            # updates). Run it as a batch of two views, so alone and in a group are one kernel.
            two = (2, -1, -1)
            return torch.baddbmm(self.bias.expand(two), x.expand(two), self.weight.expand(two))[:1]
        return torch.baddbmm(self.bias, x, self.weight)


def mlp(
    sizes: Sequence[int], gens: Sequence[torch.Generator], copies: int | None = None
) -> nn.ModuleList:
    return nn.ModuleList(Linear(a, b, gens, copies) for a, b in zip(sizes[:-1], sizes[1:]))


def relu_mlp(layers: nn.ModuleList, x: torch.Tensor) -> torch.Tensor:
    """ReLU after every layer but the last, in place (``nn.ReLU(inplace=True)``): a layer's
    output is needed by nothing else, and writing it again instead of into a fresh
    activation-sized block saves memory traffic (measured: ~5 % of a TD3 update)."""
    *hidden, last = layers  # (slicing a ModuleList builds a new module: ~40 µs a call)
    for layer in hidden:
        x = torch.relu_(layer(x))
    return last(x)


class Actor(nn.Module):
    """``K`` deterministic policies ``π(s) = tanh(MLP(s)) · scale + bias``: ``(K, B, obs)``
    -> ``(K, B, act)`` (TD3's actor; CleanRL's ``Actor``)."""

    def __init__(
        self,
        obs_dim: int,
        act_dim: int,
        hidden: Sequence[int],
        low: np.ndarray,
        high: np.ndarray,
        gens: Sequence[torch.Generator],
    ) -> None:
        super().__init__()
        self.layers = mlp([obs_dim, *hidden, act_dim], gens)
        low, high = (torch.as_tensor(np.asarray(v, np.float32)) for v in (low, high))
        self.register_buffer("action_scale", (high - low) / 2, persistent=False)
        self.register_buffer("action_bias", (high + low) / 2, persistent=False)
        self.group, self.obs_dim, self.act_dim = len(gens), obs_dim, act_dim

    def forward(self, obs: torch.Tensor) -> torch.Tensor:
        return torch.tanh(relu_mlp(self.layers, obs)) * self.action_scale + self.action_bias

    def chain(self) -> list[Linear]:
        """The layers of the exported deterministic policy (``MLPPolicy``)."""
        return list(self.layers)


class GaussianActor(nn.Module):
    """``K`` squashed Gaussian policies (SAC; CleanRL's ``Actor`` of ``sac_continuous_action``):
    a ReLU trunk, a mean head and a log-std head squashed into ``[-5, 2]``."""

    LOG_STD_MIN, LOG_STD_MAX = -5.0, 2.0

    def __init__(
        self,
        obs_dim: int,
        act_dim: int,
        hidden: Sequence[int],
        low: np.ndarray,
        high: np.ndarray,
        gens: Sequence[torch.Generator],
    ) -> None:
        super().__init__()
        self.trunk = mlp([obs_dim, *hidden], gens)
        self.mean = Linear(hidden[-1], act_dim, gens)
        self.log_std = Linear(hidden[-1], act_dim, gens)
        low, high = (torch.as_tensor(np.asarray(v, np.float32)) for v in (low, high))
        self.register_buffer("action_scale", (high - low) / 2, persistent=False)
        self.register_buffer("action_bias", (high + low) / 2, persistent=False)
        self.group, self.obs_dim, self.act_dim = len(gens), obs_dim, act_dim

    def forward(self, obs: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        h = obs
        for layer in self.trunk:
            h = torch.relu_(layer(h))
        log_std = torch.tanh(self.log_std(h))
        span = self.LOG_STD_MAX - self.LOG_STD_MIN
        return self.mean(h), self.LOG_STD_MIN + 0.5 * span * (log_std + 1)

    def sample(self, obs: torch.Tensor, eps: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """A reparameterised action ``tanh(μ + σ ε)`` (ε given: drawn from each run's generator)
        and its log-probability (with the tanh correction), ``(K, B, act)`` and ``(K, B)``."""
        mean, log_std = self(obs)
        std = log_std.exp()
        u = mean + std * eps
        y = torch.tanh(u)
        log_prob = -0.5 * eps.square() - log_std - 0.5 * math.log(2 * math.pi)
        log_prob = log_prob - torch.log(self.action_scale * (1 - y.square()) + 1e-6)
        return y * self.action_scale + self.action_bias, log_prob.sum(-1)

    def chain(self) -> list[Linear]:
        """The deterministic policy ``tanh(μ(s))`` exported for evaluation."""
        return [*self.trunk, self.mean]


class Critic(nn.Module):
    """``n`` Q-networks per run over ``(s, a[, ω])`` for ``K`` runs: ``(K, B, in)`` ->
    ``(K, n, B)``; both of a run's critics are entries of the same batched layer."""

    def __init__(
        self, in_dim: int, hidden: Sequence[int], gens: Sequence[torch.Generator], n: int = 2
    ) -> None:
        super().__init__()
        self.layers = mlp([in_dim, *hidden, 1], gens, copies=n)
        self.n, self.group = n, len(gens)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        k, b = x.shape[:2]
        x = x.unsqueeze(1).expand(k, self.n, *x.shape[1:]).reshape(k * self.n, b, -1)
        return relu_mlp(self.layers, x).view(k, self.n, b)

    def q1(self, x: torch.Tensor) -> torch.Tensor:
        """The first critic only, ``(K, B)`` (TD3's actor loss): views of its weights."""
        for i, layer in enumerate(self.layers):
            x = torch.baddbmm(layer.bias[:, 0], x, layer.weight[:, 0])
            if i < len(self.layers) - 1:
                x = torch.relu_(x)
        return x.squeeze(-1)


class NumpyActor:
    """Run ``k``'s deterministic policy in numpy, on views of the (CPU) parameters.

    Why: training acts once per env step, and a batch-1 torch call costs ~60 µs of dispatch
    against ~10 µs here. The views follow the parameters, which ``torch.optim`` and
    ``load_state_dict`` update in place. Equal to the module up to float32 rounding.
    """

    def __init__(self, actor: nn.Module) -> None:
        self.layers = [
            [(m.weight[k].detach().numpy(), m.bias[k, 0].detach().numpy()) for m in actor.chain()]
            for k in range(actor.group)
        ]
        self.scale = actor.action_scale.numpy()
        self.bias = actor.action_bias.numpy()

    def __call__(self, k: int, obs: np.ndarray) -> np.ndarray:
        *hidden, (w_out, b_out) = self.layers[k]
        h = np.asarray(obs, dtype=np.float32)
        for w, b in hidden:
            h = np.maximum(h @ w + b, 0.0)
        return np.tanh(h @ w_out + b_out) * self.scale + self.bias


def deterministic(actor: nn.Module, obs: np.ndarray, fast: NumpyActor | None) -> np.ndarray:
    """Every run's deterministic action for its own observation, ``(K, obs) -> (K, act)``:
    numpy on a CPU, one batched call on a GPU."""
    if fast is not None:
        return np.stack([fast(k, o) for k, o in enumerate(obs)])
    device = actor.action_scale.device
    with torch.inference_mode():
        x = torch.as_tensor(np.asarray(obs), dtype=torch.float32, device=device).unsqueeze(1)
        out = actor(x) if isinstance(actor, Actor) else _squashed_mean(actor, x)
        return out.squeeze(1).cpu().numpy()


def _squashed_mean(actor: GaussianActor, x: torch.Tensor) -> torch.Tensor:
    return torch.tanh(actor(x)[0]) * actor.action_scale + actor.action_bias


def to_mlp_policy(actor: nn.Module, k: int, metadata: dict | None = None):
    """Run ``k``'s deterministic policy as the ``MLPPolicy`` that evaluation reads."""
    from rrls.evaluation.policies import MLPPolicy

    return MLPPolicy(
        [m.weight[k].detach().cpu().numpy() for m in actor.chain()],
        [m.bias[k, 0].detach().cpu().numpy() for m in actor.chain()],
        actor.action_scale.cpu().numpy(),
        actor.action_bias.cpu().numpy(),
        metadata=metadata,
    )


@torch.no_grad()
def polyak(
    target: nn.Module | list[torch.Tensor], source: nn.Module | list[torch.Tensor], tau: float
) -> None:
    """``θ' ← θ' + τ (θ - θ')``, for modules or for lists of their parameters (listed once by
    a learner that averages at every update: walking a module's parameters costs ~20 µs)."""
    if isinstance(target, nn.Module):
        target, source = list(target.parameters()), list(source.parameters())
    for t, s in zip(target, source):
        t.lerp_(s, tau)
