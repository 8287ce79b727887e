"""Actor and twin critic of the paper (Appendix, "Actor/Critic architecture"): 256-256 MLPs,
held for a *group* of ``K`` independent runs at once.

Every parameter has a leading group dimension ``K`` (one slice per run; a run alone is a group
of one), and every layer of all ``K`` runs is one batched matmul (``torch.baddbmm``). Why: many
small runs in one process pay the per-operation dispatch once instead of ``K`` times, share the
cores without oversubscribing them, and on a GPU fill it. Each slice is computed by the same
matmul kernel as a lone ``addmm`` (PyTorch's CPU ``bmm`` calls the GEMM once per batch entry;
``tests/test_group.py`` checks it), so a run's numbers do not depend on its group.

The two critics of a run are two more slices (``K·2`` batch entries per layer). Both networks
offer explicit back-propagation (``forward_saved`` / ``backward_saved``): the TD3 update calls
these instead of autograd, because at these sizes (256-256, batch 256, on a CPU) autograd's
per-operation bookkeeping cost ~20 % of an update. The gradients are autograd's (tests compare
them); ``forward`` stays the differentiable path for everything else.

Initialisation is PyTorch's ``nn.Linear`` default, drawn per run from the run's own seeded
generator, so a run's initial weights do not depend on the group either.
"""

from __future__ import annotations

import copy
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


def _linear(b: torch.Tensor, h: torch.Tensor, w: torch.Tensor, w_t: torch.Tensor) -> torch.Tensor:
    """``b + h @ w`` for every batch entry. A layer of one output unit is a multiply-and-sum:
    MKL computes a lone one-column product (a group of one run) with another kernel than a
    batch of them, which rounds differently; the sum does not depend on the batch (measured in
    ``tests/test_group.py``)."""
    if w.shape[-1] == 1:
        return torch.add(b, (h * w_t).sum(-1, keepdim=True))
    return torch.baddbmm(b, h, w)


_ALIGN = 64  # elements: a multiple of any SIMD width times PyTorch's loop unrolling
_GRAIN = 32_768  # PyTorch's elementwise grain size: larger tensors are split over threads


def per_run(fn, x: torch.Tensor) -> torch.Tensor:  # noqa: ANN001
    """``fn(x)`` for a transcendental ``fn`` (tanh, sigmoid), the same for a run in any group.

    Why: PyTorch's CPU kernels compute an element with SIMD code or, at the end of a block,
    with scalar code, and the two round transcendental functions differently; which element
    falls where depends on its offset in the whole tensor, hence on the other runs (measured: a
    sigmoid 1 ulp apart). Each run's slice is laid out from a multiple of ``_ALIGN`` and the
    calls stay within one thread's block, so every run's elements get the same treatment.
    """
    k, m = x.shape[0], x[0].numel()
    width = -(-m // _ALIGN) * _ALIGN
    if x.device.type != "cpu" or (width == m and k * m <= _GRAIN and x.is_contiguous()):
        return fn(x)
    padded = x.new_zeros((k, width))
    padded[:, :m] = x.reshape(k, m)
    per_call = max(1, _GRAIN // width)
    out = torch.cat([fn(padded[i : i + per_call]) for i in range(0, k, per_call)])
    return out[:, :m].reshape(x.shape)


def padded(values: torch.Tensor) -> torch.Tensor:
    """``values`` (runs first) copied into the rows of a zero ``(K, P)`` buffer, ``P`` a multiple
    of ``_ALIGN`` (``rows`` gives it back).

    Why: each run's slice then starts at the same SIMD phase, so elementwise kernels run over the
    rows (fused Adam, Polyak averaging) treat every run alike; over a compact tensor, a run's
    3 output biases were measured 1 ulp apart depending on the group. On a GPU layouts do not
    matter and the tensor stays compact.
    """
    k, width = values.shape[0], _row_width(values)
    store = values.new_zeros((k, width))
    store[:, : values[0].numel()] = values.reshape(k, -1)
    return store.as_strided(values.shape, _row_strides(values.shape, width))


def rows(t: torch.Tensor) -> torch.Tensor:
    """The ``(K, P)`` rows behind a ``padded`` tensor, padding included."""
    width = _row_width(t)
    return t.detach().as_strided((t.shape[0], width), (width, 1))


def _row_width(t: torch.Tensor) -> int:
    m = t[0].numel()
    return -(-m // _ALIGN) * _ALIGN if t.device.type == "cpu" else m


def _row_strides(shape: torch.Size, width: int) -> tuple[int, ...]:
    inner = [1]
    for size in reversed(shape[2:]):
        inner.insert(0, inner[0] * size)
    return (width, *inner) if len(shape) > 1 else (width,)


class _Padded:
    """Modules whose parameters are ``padded`` (re-done after a deep copy, which compacts them)."""

    def pad_(self) -> _Padded:
        # not under no_grad: a view made there may not be used where autograd records
        for plist in (self.weights, self.biases):
            for i, p in enumerate(plist):
                plist[i] = nn.Parameter(padded(p.data), requires_grad=p.requires_grad)
        self.__dict__.pop("_view_cache", None)
        return self

    def __deepcopy__(self, memo: dict) -> _Padded:
        clone = copy.copy(self)
        clone.__dict__ = {
            k: copy.deepcopy(v, memo) for k, v in self.__dict__.items() if k != "_view_cache"
        }
        return clone.pad_()


def _bmm(x: torch.Tensor, w: torch.Tensor) -> torch.Tensor:
    """``x @ w`` per batch entry; one output column as a multiply-and-sum (see ``_linear``)."""
    if w.shape[-1] == 1:
        return (x * w.transpose(1, 2)).sum(-1, keepdim=True)
    return torch.bmm(x, w)


def _weight_grad(x: torch.Tensor, d: torch.Tensor, out: torch.Tensor) -> None:
    """``out = xᵀ d`` per batch entry, with the wider of the two as the product's rows.

    Why: for one batch entry MKL splits a product with few rows (an input layer of 5 or 11
    observations) over threads, summing in another order than for a batch; with many rows it
    does not (measured over the paper's layer shapes, ``tests/test_group.py``).
    """
    if x.shape[-1] < d.shape[-1]:
        out.copy_(torch.bmm(d.transpose(1, 2), x).transpose(1, 2))
    else:
        torch.bmm(x.transpose(1, 2), d, out=out)


def _uniform(shape: tuple[int, ...], bound: float, gen: torch.Generator) -> torch.Tensor:
    return torch.empty(shape).uniform_(-bound, bound, generator=gen)


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


class Actor(_Padded, _ViewCache, nn.Module):
    """``K`` deterministic policies: ReLU hidden layers, tanh output scaled to the action box.

    ``weights[i]`` is ``(K, fan_in, fan_out)`` (already transposed for ``x @ W``), ``biases[i]``
    ``(K, 1, fan_out)``. Inputs are ``(K, B, obs_dim)``.
    """

    def __init__(
        self,
        obs_dim: int,
        act_dim: int,
        hidden: Sequence[int] = (256, 256),
        action_low: np.ndarray | float = -1.0,
        action_high: np.ndarray | float = 1.0,
        generators: Sequence[torch.Generator] | None = None,
    ) -> None:
        super().__init__()
        gens = list(generators) if generators is not None else [torch.default_generator]
        sizes = [obs_dim, *hidden, act_dim]
        per_run = [
            [
                (_uniform((b, a), 1 / math.sqrt(a), g).t(), _uniform((1, b), 1 / math.sqrt(a), g))
                for a, b in zip(sizes[:-1], sizes[1:])
            ]
            for g in gens
        ]
        self.weights = nn.ParameterList(
            nn.Parameter(torch.stack([run[i][0] for run in per_run]).contiguous())
            for i in range(len(sizes) - 1)
        )
        self.biases = nn.ParameterList(
            nn.Parameter(torch.stack([run[i][1] for run in per_run])) for i in range(len(sizes) - 1)
        )
        low = torch.tensor(np.broadcast_to(action_low, (act_dim,)), dtype=torch.float32)
        high = torch.tensor(np.broadcast_to(action_high, (act_dim,)), dtype=torch.float32)
        self.register_buffer("action_scale", (high - low) / 2)
        self.register_buffer("action_bias", (high + low) / 2)
        self.group, self.obs_dim, self.act_dim = len(gens), obs_dim, act_dim
        self.pad_()

    def _layers(self) -> list[tuple[torch.Tensor, torch.Tensor, torch.Tensor]]:
        """``(weights, biases, weights transposed)`` per layer, cached (``_ViewCache``)."""
        return self._views(
            "layers",
            lambda: [
                (w, b, w.transpose(1, 2))
                for w, b in zip(self.weights._parameters.values(), self.biases._parameters.values())
            ],
        )

    def forward(self, obs: torch.Tensor) -> torch.Tensor:
        """``(K, B, obs_dim) -> (K, B, act_dim)``, differentiable."""
        return self.forward_saved(obs)[0]

    def forward_saved(self, obs: torch.Tensor) -> tuple[torch.Tensor, list[torch.Tensor]]:
        """``forward`` keeping the activations ``backward_saved`` needs."""
        *hidden, (w_out, b_out, layers_out_t) = self._layers()
        saved = [obs]
        h = obs
        for w, b, w_t in hidden:
            h = _linear(b, h, w, w_t).relu_()
            saved.append(h)
        t = per_run(torch.tanh, _linear(b_out, h, w_out, layers_out_t))
        saved.append(t)
        return torch.addcmul(self.action_bias, t, self.action_scale), saved

    def backward_saved(
        self, saved: list[torch.Tensor], grad_action: torch.Tensor, grads: list[torch.Tensor]
    ) -> None:
        """Write ``d(Σ grad_action · π(s)) / dθ`` into ``grads`` (ordered as ``parameters()``:
        weights, then biases)."""
        *inputs, t = saved
        layers = self._layers()
        depth = len(layers)
        d = grad_action * self.action_scale * (1.0 - t * t)  # through scale · tanh
        for i in reversed(range(depth)):
            _weight_grad(inputs[i], d, grads[i])
            torch.sum(d, 1, keepdim=True, out=grads[depth + i])
            if i:
                d = _relu_backward_(_bmm(d, layers[i][2]), inputs[i])

    def act_one(self, k: int, obs: np.ndarray) -> np.ndarray:
        """Run ``k``'s π(s) for one observation, in numpy on views of the (CPU) weights.

        Why: training acts once per env step, and a batch-1 torch call costs ~60 µs of dispatch
        there against ~10 µs here. Equal to ``forward`` up to float32 rounding.
        """
        h = np.asarray(obs, dtype=np.float32)
        *hidden, (w_out, b_out), scale, bias = self._views(("numpy", k), lambda: self._numpy(k))
        for w, b in hidden:
            h = np.maximum(h @ w + b, 0.0)
        return np.tanh(h @ w_out + b_out) * scale + bias

    def _numpy(self, k: int) -> list:
        views: list = [
            (w[k].detach().numpy(), b[k, 0].detach().numpy()) for w, b, _ in self._layers()
        ]
        return views + [self.action_scale.numpy(), self.action_bias.numpy()]

    def to_mlp_policy(self, k: int = 0, metadata: dict | None = None):  # noqa: ANN201
        """Run ``k``'s actor as a numpy ``MLPPolicy`` (the safe ``.npz`` that evaluation reads)."""
        from rrls.evaluation.policies import MLPPolicy

        return MLPPolicy(
            [w[k].detach().cpu().numpy() for w in self.weights],
            [b[k, 0].detach().cpu().numpy() for b in self.biases],
            self.action_scale.cpu().numpy(),
            self.action_bias.cpu().numpy(),
            metadata=metadata,
        )


class TwinCritic(_Padded, _ViewCache, nn.Module):
    """``n`` Q-networks per run over the same input, for ``K`` runs: output ``(K, n, B)``.

    ``weights[i]`` is ``(K·n, fan_in, fan_out)``: run ``k``'s critic ``j`` is entry ``k·n + j``.
    """

    def __init__(
        self,
        in_dim: int,
        hidden: Sequence[int] = (256, 256),
        n: int = 2,
        generators: Sequence[torch.Generator] | None = None,
    ) -> None:
        super().__init__()
        gens = list(generators) if generators is not None else [torch.default_generator]
        sizes = [in_dim, *hidden, 1]
        per_run = [
            [
                (
                    _uniform((n, a, b), 1 / math.sqrt(a), g),  # nn.Linear's default, per critic
                    _uniform((n, 1, b), 1 / math.sqrt(a), g),
                )
                for a, b in zip(sizes[:-1], sizes[1:])
            ]
            for g in gens
        ]
        self.weights = nn.ParameterList(
            nn.Parameter(torch.cat([run[i][0] for run in per_run])) for i in range(len(sizes) - 1)
        )
        self.biases = nn.ParameterList(
            nn.Parameter(torch.cat([run[i][1] for run in per_run])) for i in range(len(sizes) - 1)
        )
        self.n, self.group = n, len(gens)
        self.pad_()

    def _layers(self, n: int) -> list[tuple[torch.Tensor, ...]]:
        """``(weights, biases, weights transposed)`` of each run's first ``n`` critics per layer,
        cached (``_ViewCache``): strided views, no copies."""

        def make() -> list[tuple[torch.Tensor, ...]]:
            out = []
            pairs = zip(self.weights._parameters.values(), self.biases._parameters.values())
            for w, b in pairs:
                if n != self.n:
                    k = self.group
                    w = w.view(k, self.n, *w.shape[1:])[:, :n].flatten(0, 1)
                    b = b.view(k, self.n, *b.shape[1:])[:, :n].flatten(0, 1)
                out.append((w, b, w.transpose(1, 2)))
            return out

        return self._views(("layers", n), make)

    def forward(self, x: torch.Tensor, n: int | None = None) -> torch.Tensor:
        """``(K, B, in_dim) -> (K, n, B)``, differentiable."""
        return self.forward_saved(x, n)[0]

    def forward_saved(
        self, x: torch.Tensor, n: int | None = None
    ) -> tuple[torch.Tensor, list[torch.Tensor]]:
        """Each run's first ``n`` critics, ``(K, n, B)``, keeping the activations."""
        n = self.n if n is None else n
        layers = self._layers(n)
        k, batch = x.shape[0], x.shape[1]
        h = x if n == 1 else x.unsqueeze(1).expand(k, n, *x.shape[1:]).flatten(0, 1)
        saved = [h]
        last = len(layers) - 1
        for i, (w, b, w_t) in enumerate(layers):
            h = _linear(b, h, w, w_t)
            if i < last:
                h = h.relu_()
                saved.append(h)
        return h.view(k, n, batch), saved

    def backward_saved(
        self,
        saved: list[torch.Tensor],
        grad_q: torch.Tensor,
        grads: list[torch.Tensor] | None = None,
        input_columns: slice | None = None,
    ) -> torch.Tensor | None:
        """Back-propagate ``grad_q`` (``(K, n, B)``, ``n`` as in ``forward_saved``).

        Writes the parameter gradients into ``grads`` (ordered as ``parameters()``: weights,
        then biases; only for ``n`` = all critics) unless it is ``None``; returns
        ``d/dx[..., input_columns]`` summed over the ``n`` critics, ``(K, B, columns)``, if asked
        (the actor loss needs the gradient with respect to the action columns only).
        """
        k, n, batch = grad_q.shape
        layers = self._layers(n)
        depth = len(layers)
        d = grad_q.reshape(k * n, batch, 1)
        for i in reversed(range(depth)):
            if grads is not None:
                _weight_grad(saved[i], d, grads[i])
                torch.sum(d, 1, keepdim=True, out=grads[depth + i])
            if i:
                w_t = layers[i][2]
                # the output layer has one unit: its backward is a broadcast product, not a matmul
                dh = d * w_t if i == depth - 1 else _bmm(d, w_t)
                d = _relu_backward_(dh, saved[i])
        if input_columns is None:
            return None
        cols = (input_columns.start, input_columns.stop)
        w_in_t = self._views(
            ("input columns", n, cols), lambda: layers[0][0][:, input_columns].transpose(1, 2)
        )
        dx = _bmm(d, w_in_t)
        return dx if n == 1 else dx.view(k, n, batch, -1).sum(1)
