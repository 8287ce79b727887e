"""Actor and twin critic of the paper (Appendix, "Actor/Critic architecture"): 256-256 MLPs.

The two critics live in one module with stacked weights, so each layer of both is a single
batched matmul (``torch.baddbmm``) instead of two small ones — the same mathematics as two
separate ``nn.Linear`` stacks, initialised the same way (PyTorch's Linear default).

Both networks also offer explicit back-propagation (``forward_saved`` / ``backward_saved``): the
TD3 update calls these instead of autograd, because at these sizes (256-256, batch 256, on a
CPU) autograd's per-operation bookkeeping cost ~20 % of an update. The gradients are
autograd's (tests compare them); ``forward`` stays the differentiable path for everything else.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
import torch
from torch import nn


def _relu_backward_(grad: torch.Tensor, output: torch.Tensor) -> torch.Tensor:
    """ReLU's backward in place: ``grad`` where the saved ``output`` is positive, else 0.

    Autograd's own op (``threshold_backward``), written into ``grad`` instead of a new tensor:
    ~1 % of an update saved by not allocating (and first-touching) another activation-sized block.
    """
    return torch.ops.aten.threshold_backward.grad_input(grad, output, 0, grad_input=grad)


class _ViewCache:
    """Views of a module's parameters (transposes, slices, numpy arrays) made once, not per call.

    Why: at an update's ~100 operations, each view op costs a few µs, more in a training loop
    whose caches the env step has just evicted. The views stay current because optimisers,
    Polyak averaging and ``load_state_dict`` write into the parameters in place; anything that
    moves them to new storage (``.to()``, ``load_state_dict(assign=True)``) drops the cache.
    """

    def _views(self, key: object, make):  # noqa: ANN001, ANN202
        # per grad mode: a view made under no_grad would not carry gradients in a graph
        key = (key, torch.is_grad_enabled())
        cache = self.__dict__.setdefault("_view_cache", {})
        if key not in cache:
            cache[key] = make()
        return cache[key]

    def _apply(self, fn, recurse=True):  # noqa: ANN001, ANN202 - nn.Module's signature
        self.__dict__.pop("_view_cache", None)
        return super()._apply(fn, recurse)

    def _load_from_state_dict(self, *args, **kwargs) -> None:  # noqa: ANN002, ANN003
        self.__dict__.pop("_view_cache", None)
        super()._load_from_state_dict(*args, **kwargs)

    def __getstate__(self) -> dict:
        state = dict(self.__dict__)  # deepcopy and pickling rebuild the views, not copy them
        state.pop("_view_cache", None)
        return state


class Actor(_ViewCache, nn.Module):
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

    def _layers(self) -> list[tuple[torch.Tensor, torch.Tensor, torch.Tensor]]:
        """``(weight, bias, weight.T)`` per layer, cached (``_ViewCache``)."""
        return self._views(
            "layers",
            lambda: [(m.weight, m.bias, m.weight.t()) for m in self.layers],
        )

    def act_one(self, obs: np.ndarray) -> np.ndarray:
        """π(s) for one observation, in numpy on views of the (CPU) weights.

        Why: training acts once per env step, and a batch-1 torch forward costs ~60 µs of
        dispatch there against ~10 µs here. Equal to ``forward`` up to float32 rounding.
        """
        h = np.asarray(obs, dtype=np.float32)
        *hidden, (w_out, b_out), scale, bias = self._views("numpy", self._numpy_views)
        for w, b in hidden:
            h = np.maximum(w @ h + b, 0.0)
        return np.tanh(w_out @ h + b_out) * scale + bias

    def _numpy_views(self) -> list:
        views: list = [(w.detach().numpy(), b.detach().numpy()) for w, b, _ in self._layers()]
        return views + [self.action_scale.numpy(), self.action_bias.numpy()]

    def forward_saved(self, obs: torch.Tensor) -> tuple[torch.Tensor, list[torch.Tensor]]:
        """``forward`` without a graph, keeping the activations ``backward_saved`` needs."""
        *hidden, (_, b_out, w_out_t) = self._layers()
        saved = [obs]
        h = obs
        for _, b, w_t in hidden:
            h = torch.addmm(b, h, w_t).relu_()
            saved.append(h)
        t = torch.addmm(b_out, h, w_out_t).tanh_()
        saved.append(t)
        return torch.addcmul(self.action_bias, t, self.action_scale), saved

    def backward_saved(
        self, saved: list[torch.Tensor], grad_action: torch.Tensor, grads: list[torch.Tensor]
    ) -> None:
        """Write ``d(Σ grad_action · π(s)) / dθ`` into ``grads`` (ordered as ``parameters()``)."""
        *inputs, t = saved
        layers = self._layers()
        d = grad_action * self.action_scale * (1.0 - t * t)  # through scale · tanh
        for i in reversed(range(len(layers))):
            torch.mm(d.t(), inputs[i], out=grads[2 * i])
            torch.sum(d, 0, out=grads[2 * i + 1])
            if i:
                d = _relu_backward_(torch.mm(d, layers[i][0]), inputs[i])

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


class TwinCritic(_ViewCache, nn.Module):
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

    def _layers(self, n: int | None = None) -> list[tuple[torch.Tensor, ...]]:
        """``(weights, biases, weights transposed)`` of the first ``n`` critics per layer, cached
        (``_ViewCache``): no ``ParameterList`` indexing, slicing or transposing per call."""
        n = self.n if n is None else n

        def make() -> list[tuple[torch.Tensor, ...]]:
            pairs = zip(self.weights._parameters.values(), self.biases._parameters.values())
            if n == self.n:
                return [(w, b, w.transpose(1, 2)) for w, b in pairs]
            return [(w[:n], b[:n], w[:n].transpose(1, 2)) for w, b in pairs]

        return self._views(("layers", n), make)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        # the same ops as forward_saved (in-place ReLUs are fine for autograd: baddbmm's
        # backward does not need its output)
        return self.forward_saved(x)[0]

    def forward_saved(
        self, x: torch.Tensor, n: int | None = None
    ) -> tuple[torch.Tensor, list[torch.Tensor]]:
        """The first ``n`` critics' ``(n, B)`` values without a graph, keeping the activations."""
        layers = self._layers(n)
        h = x.expand(len(layers[0][0]), *x.shape)
        saved = [h]
        last = len(layers) - 1
        for i, (w, b, _) in enumerate(layers):
            h = torch.baddbmm(b, h, w)
            if i < last:
                h = h.relu_()
                saved.append(h)
        return h.squeeze(-1), saved

    def backward_saved(
        self,
        saved: list[torch.Tensor],
        grad_q: torch.Tensor,
        grads: list[torch.Tensor] | None = None,
        input_columns: slice | None = None,
    ) -> torch.Tensor | None:
        """Back-propagate ``grad_q`` (``(n, B)``, ``n`` as in ``forward_saved``).

        Writes the parameter gradients into ``grads`` (ordered as ``parameters()``: weights,
        then biases) unless it is ``None``; returns ``d/dx[..., input_columns]`` if asked (the
        actor loss needs the gradient with respect to the action columns only).
        """
        n = grad_q.shape[0]
        layers = self._layers(n)
        depth = len(layers)
        d = grad_q.unsqueeze(-1)
        for i in reversed(range(depth)):
            if grads is not None:
                torch.bmm(saved[i].transpose(1, 2), d, out=grads[i])
                torch.sum(d, 1, keepdim=True, out=grads[depth + i])
            if i:
                w_t = layers[i][2]
                # the output layer has one unit: its backward is a broadcast product, not a matmul
                dh = d * w_t if i == depth - 1 else torch.bmm(d, w_t)
                d = _relu_backward_(dh, saved[i])
        if input_columns is None:
            return None
        cols = (input_columns.start, input_columns.stop)
        w_in_t = self._views(
            ("input columns", n, cols), lambda: layers[0][0][:, input_columns].transpose(1, 2)
        )
        return torch.bmm(d, w_in_t)

    def q1(self, x: torch.Tensor) -> torch.Tensor:
        """The first critic only (TD3's actor loss): half the work of ``forward``."""
        h = x
        last = len(self.weights) - 1
        for i, (w, b) in enumerate(zip(self.weights, self.biases)):
            h = torch.addmm(b[0], h, w[0])
            if i < last:
                h = torch.relu(h)
        return h.squeeze(-1)
