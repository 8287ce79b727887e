"""Policies as the evaluation engine sees them: a batch of observations in, a batch of actions out.

Why fixed-size blocks: BLAS libraries pick different kernels for different batch sizes, so a row's
output can change in the last bits with the number of rows next to it, and over 1 000 chaotic
steps that becomes a different return. Running every call in zero-padded blocks of a fixed size
makes each row's output independent of the batch, so the engine's lockstep batches give exactly
what ``policy(obs[None])[0]`` gives one episode at a time.

>>> import numpy as np
>>> policy = MLPPolicy.random(obs_dim=3, act_dim=2, hidden=(8, 8), seed=0)
>>> obs = np.random.default_rng(1).normal(size=(70, 3))
>>> bool(np.array_equal(policy(obs)[5], policy(obs[5:6])[0]))
True
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any, Protocol, runtime_checkable

import numpy as np

BLOCK = 64  # rows per policy call inside BatchInvariant (invariance measured in tests)


@runtime_checkable
class Policy(Protocol):
    """Anything mapping observations ``[B, obs_dim]`` to actions ``[B, act_dim]``."""

    def __call__(self, obs: np.ndarray) -> np.ndarray: ...


class BatchInvariant:
    """Wrap a batch policy so that each row's action does not depend on the batch around it.

    Every call is cut into blocks of ``block`` rows (the last one zero-padded), so the wrapped
    policy always sees the same shape. Costs a little at batch 1, nothing at large batches.
    """

    def __init__(self, policy: Callable[[np.ndarray], Any], block: int = BLOCK) -> None:
        if block < 1:
            raise ValueError(f"block must be >= 1, got {block}")
        self.policy = policy
        self.block = int(block)

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        obs = np.asarray(obs)
        n, block = len(obs), self.block
        if n == block:
            return np.asarray(self.policy(obs))
        padded = np.zeros((max(block, -(-n // block) * block), *obs.shape[1:]), dtype=obs.dtype)
        padded[:n] = obs
        if len(padded) == block:
            return np.asarray(self.policy(padded))[:n]
        outs = [
            np.asarray(self.policy(padded[i : i + block])) for i in range(0, len(padded), block)
        ]
        return np.concatenate(outs)[:n]

    def __repr__(self) -> str:
        return f"BatchInvariant({self.policy!r}, block={self.block})"


class MLPPolicy:
    """A numpy MLP actor (ReLU hidden layers, tanh output scaled to the action box).

    The safe file format: ``save``/``load`` use a plain ``.npz`` of arrays plus a JSON header,
    read with ``allow_pickle=False`` — loading a policy never runs code.
    """

    def __init__(
        self,
        weights: Sequence[np.ndarray],
        biases: Sequence[np.ndarray],
        action_scale: np.ndarray | float = 1.0,
        action_bias: np.ndarray | float = 0.0,
        dtype: Any = np.float32,
        metadata: dict[str, Any] | None = None,
    ) -> None:
        if len(weights) != len(biases) or not weights:
            raise ValueError("an MLP needs as many bias vectors as weight matrices (at least one)")
        self.weights = [np.ascontiguousarray(w, dtype=dtype) for w in weights]
        self.biases = [np.ascontiguousarray(b, dtype=dtype) for b in biases]
        for i, (w, b) in enumerate(zip(self.weights, self.biases)):
            if w.ndim != 2 or b.shape != (w.shape[1],):
                raise ValueError(f"layer {i}: weight {w.shape} and bias {b.shape} do not match")
            if i and w.shape[0] != self.weights[i - 1].shape[1]:
                raise ValueError(
                    f"layer {i} expects {w.shape[0]} inputs, gets {self.weights[i - 1].shape[1]}"
                )
        act_dim = self.weights[-1].shape[1]
        self.action_scale = np.broadcast_to(
            np.asarray(action_scale, dtype=dtype), (act_dim,)
        ).copy()
        self.action_bias = np.broadcast_to(np.asarray(action_bias, dtype=dtype), (act_dim,)).copy()
        self.dtype = np.dtype(dtype)
        self.metadata = dict(metadata or {})
        self._invariant = BatchInvariant(self._forward)

    @property
    def obs_dim(self) -> int:
        return self.weights[0].shape[0]

    @property
    def act_dim(self) -> int:
        return self.weights[-1].shape[1]

    @classmethod
    def random(
        cls,
        obs_dim: int,
        act_dim: int,
        hidden: Sequence[int] = (256, 256),
        seed: int = 0,
        dtype: Any = np.float32,
    ) -> MLPPolicy:
        """Fixed random weights (He-uniform like PyTorch's Linear): for tests and benchmarks."""
        rng = np.random.default_rng(seed)
        sizes = [obs_dim, *hidden, act_dim]
        weights, biases = [], []
        for fan_in, fan_out in zip(sizes[:-1], sizes[1:]):
            bound = 1.0 / np.sqrt(fan_in)
            weights.append(rng.uniform(-bound, bound, size=(fan_in, fan_out)))
            biases.append(rng.uniform(-bound, bound, size=fan_out))
        return cls(weights, biases, dtype=dtype)

    def _forward(self, obs: np.ndarray) -> np.ndarray:
        h = obs.astype(self.dtype, copy=False)
        last = len(self.weights) - 1
        for i, (w, b) in enumerate(zip(self.weights, self.biases)):
            h = h @ w
            h += b
            if i < last:
                np.maximum(h, 0, out=h)
        return np.tanh(h) * self.action_scale + self.action_bias

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        obs = np.asarray(obs)
        if obs.ndim != 2 or obs.shape[1] != self.obs_dim:
            raise ValueError(f"expected observations of shape (B, {self.obs_dim}), got {obs.shape}")
        return self._invariant(obs)

    def save(self, path: str | Path) -> Path:
        """Write ``path`` (``.npz``) atomically."""
        from rrls._io import atomic_save_npz

        arrays: dict[str, np.ndarray] = {}
        for i, (w, b) in enumerate(zip(self.weights, self.biases)):
            arrays[f"w{i}"], arrays[f"b{i}"] = w, b
        arrays["action_scale"], arrays["action_bias"] = self.action_scale, self.action_bias
        header = {
            "format": "rrls-mlp",
            "version": 1,
            "layers": len(self.weights),
            "metadata": self.metadata,
        }
        arrays["header"] = np.frombuffer(json.dumps(header).encode(), dtype=np.uint8)
        return atomic_save_npz(path, **arrays)

    @classmethod
    def load(cls, path: str | Path) -> MLPPolicy:
        """Read a file written by :meth:`save`; anything else is refused (never unpickled)."""
        try:
            with np.load(path, allow_pickle=False) as f:
                if not hasattr(f, "files") or "header" not in f:
                    raise ValueError("no header")
                header = json.loads(bytes(f["header"]).decode())
                if header.get("format") != "rrls-mlp":
                    raise ValueError(f"unknown policy format {header.get('format')!r}")
                n = int(header["layers"])
                weights = [f[f"w{i}"] for i in range(n)]
                biases = [f[f"b{i}"] for i in range(n)]
                scale, bias = f["action_scale"], f["action_bias"]
        except FileNotFoundError:
            raise
        except Exception as err:  # noqa: BLE001 - any unreadable content: one clear message
            reason = str(err)
            if "pickle" in reason or not isinstance(err, (KeyError, ValueError)) or not reason:
                reason = "not an .npz archive"  # never suggest unpickling an unknown file
            raise ValueError(
                f"{path} is not an rrls MLP policy file (an .npz written by rrls): {reason}"
            ) from None
        return cls(
            weights, biases, scale, bias, dtype=weights[0].dtype, metadata=header.get("metadata")
        )

    def __repr__(self) -> str:
        sizes = [self.obs_dim] + [w.shape[1] for w in self.weights]
        return f"MLPPolicy({'-'.join(map(str, sizes))}, {self.dtype})"


class TorchPolicy:
    """Adapter for a torch ``nn.Module`` actor: numpy in and out, no autograd, batch-invariant."""

    def __init__(self, module: Any, device: str = "cpu", block: int = BLOCK) -> None:
        import torch

        self.module = module.eval()
        self.device = torch.device(device)
        self.dtype = next(module.parameters()).dtype
        self._invariant = BatchInvariant(self._forward, block)

    def _forward(self, obs: np.ndarray) -> np.ndarray:
        import torch

        with torch.inference_mode():
            x = torch.as_tensor(obs, dtype=self.dtype, device=self.device)
            return self.module(x).cpu().numpy()

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        return self._invariant(np.asarray(obs))


class SB3Policy:
    """Adapter for a Stable-Baselines3 model: ``model.predict(obs, deterministic=True)[0]``."""

    def __init__(self, model: Any, block: int = BLOCK) -> None:
        self.model = model
        self._invariant = BatchInvariant(self._forward, block)

    def _forward(self, obs: np.ndarray) -> np.ndarray:
        return np.asarray(self.model.predict(obs, deterministic=True)[0])

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        return self._invariant(np.asarray(obs))


def as_policy(obj: Any) -> Callable[[np.ndarray], np.ndarray]:
    """Adapt ``obj``: a path (policy file or run), a torch module, an SB3 model, a callable."""
    if isinstance(obj, (str, Path)):
        return load_policy(obj)
    module_names = {c.__module__.split(".")[0] for c in type(obj).__mro__}
    if "torch" in module_names and hasattr(obj, "parameters"):
        return TorchPolicy(obj)
    if hasattr(obj, "predict") and hasattr(obj, "policy"):
        return SB3Policy(obj)
    if callable(obj):
        return obj
    raise TypeError(
        f"cannot use {type(obj).__name__} as a policy: expected a callable obs -> action"
    )


def load_policy(path: str | Path) -> Callable[[np.ndarray], np.ndarray]:
    """Load a saved policy: an ``.npz`` MLP file, or a training-run directory of ``rrls train``.

    The returned policy's ``metadata`` records where it came from (``path``, ``run_dir``).
    """
    path = Path(path)
    run_dir = None
    if path.is_dir():
        from rrls.rundir import POLICY

        if not (path / POLICY).is_file():
            raise FileNotFoundError(f"{path} holds no {POLICY}: not an `rrls train` run")
        run_dir, path = path, path / POLICY
    elif not path.exists():
        raise FileNotFoundError(f"no policy file {path}")
    elif path.suffix != ".npz":
        raise ValueError(f"{path}: unknown policy file type (expected .npz or a run directory)")
    policy = MLPPolicy.load(path)
    policy.metadata.setdefault("path", str(path))
    if run_dir is not None:
        policy.metadata.setdefault("run_dir", str(run_dir))
    return policy


def policy_fingerprint(policy: Callable[[np.ndarray], Any], obs_dim: int, n: int = 8) -> str:
    """A short hash of the policy's actions on fixed probe observations (to guard resumes)."""
    probe = np.random.default_rng(12345).normal(size=(n, obs_dim))
    actions = np.ascontiguousarray(np.asarray(policy(probe), dtype=np.float64))
    return hashlib.sha256(actions.tobytes()).hexdigest()[:16]


def is_batch_invariant(policy: Callable[[np.ndarray], Any], obs_dim: int, n: int = 20) -> bool:
    """Whether rows of a batch call equal one-row calls on probe observations."""
    probe = np.random.default_rng(54321).normal(size=(n, obs_dim))
    batch = np.asarray(policy(probe))
    return all(
        np.array_equal(batch[i], np.asarray(policy(probe[i : i + 1]))[0], equal_nan=True)
        for i in range(n)
    )
