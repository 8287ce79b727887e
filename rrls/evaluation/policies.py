"""Policies as the evaluation engine sees them: a batch of observations in, a batch of actions out.

Why batch invariance matters: over 1 000 chaotic steps a last-bit difference in an action becomes
another return, so a row's action must not depend on the rows around it, or an evaluation would
depend on its batch size and worker count. rrls's own ``MLPPolicy`` computes every product in a
summation order no BLAS kernel chooses (``rrls.evaluation.exact``): row ``i`` depends on
``obs[i]`` alone, with the same bits on any CPU. Other policies (torch modules, SB3 models,
callables) are wrapped in ``BatchInvariant``: fixed-shape zero-padded blocks, which makes a row
independent of the batch *size* — exact on CPUs whose GEMM kernels treat every row position
alike, not guaranteed on all (some AVX2 kernels compute a block's last rows in another order).

>>> import numpy as np
>>> policy = MLPPolicy.random(obs_dim=3, act_dim=2, hidden=(8, 8), seed=0)
>>> obs = np.random.default_rng(1).normal(size=(70, 3))
>>> bool(np.array_equal(policy(obs)[5], policy(obs[5:6])[0]))
True
"""

from __future__ import annotations

import json
import re
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any, Protocol, runtime_checkable

import numpy as np

from rrls.evaluation.exact import ExactLinear, exact_tanh
from rrls.extras import install_hint
from rrls.files import loads_json
from rrls.schema import Schema, integer, obj, string

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


#: an ``MLPPolicy`` file's JSON header
HEADER_SCHEMA = Schema(
    {
        "format": string(choices=("rrls-mlp",), required=True),
        "version": integer(1, 1, required=True),
        "layers": integer(1, 64, required=True),
        "metadata": obj(Schema({}, open=True), null=True),
    }
)


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
        self._layers = [ExactLinear(w) for w in self.weights]
        self._bias64 = [b.astype(np.float64) for b in self.biases]

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
        # Each layer: an exact-order product (rrls.evaluation.exact), the bias, one rounding to
        # the policy's dtype (as the network it was trained as), ReLU. Row i depends on obs[i]
        # alone, with the same bits on any CPU: no BLAS kernel chooses a summation order.
        h = obs.astype(self.dtype, copy=False)
        last = len(self._layers) - 1
        for i, (layer, b) in enumerate(zip(self._layers, self._bias64)):
            h = (layer(h) + b).astype(self.dtype)
            if i < last:
                np.maximum(h, 0, out=h)
        out = exact_tanh(h) * self.action_scale + self.action_bias
        return out.astype(self.dtype)

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        obs = np.asarray(obs)
        if obs.ndim != 2 or obs.shape[1] != self.obs_dim:
            raise ValueError(f"expected observations of shape (B, {self.obs_dim}), got {obs.shape}")
        return self._forward(obs)

    def save(self, path: str | Path) -> Path:
        """Write ``path`` (``.npz``) atomically."""
        from rrls.files import atomic_save_npz

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
                header = HEADER_SCHEMA.check(loads_json(bytes(f["header"]), "header"), "header")
                n = header["layers"]
                weights = [f[f"w{i}"] for i in range(n)]
                biases = [f[f"b{i}"] for i in range(n)]
                scale, bias = f["action_scale"], f["action_bias"]
                for name, a in zip(("weights", "biases"), (weights, biases)):
                    if not all(np.isfinite(x).all() for x in a):
                        raise ValueError(f"its {name} hold NaN or inf (a diverged training?)")
        except FileNotFoundError:
            raise
        except Exception as err:  # noqa: BLE001 - any unreadable content: one clear message
            reason = str(err)
            if "pickle" in reason or not isinstance(err, (KeyError, ValueError)) or not reason:
                reason = "not an .npz archive"  # never suggest unpickling an unknown file
            raise ValueError(
                f"{path} is not an rrls MLP policy file (an .npz written by rrls): {reason}"
            ) from None
        try:
            return cls(
                weights,
                biases,
                scale,
                bias,
                dtype=weights[0].dtype,
                metadata=header.get("metadata"),
            )
        except ValueError as err:  # shapes that do not chain
            raise ValueError(f"{path} is not a usable rrls MLP policy: {err}") from None

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
        self.metadata: dict[str, Any] = {}
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
        self.metadata: dict[str, Any] = {}
        self._invariant = BatchInvariant(self._forward, block)

    @property
    def obs_shape(self) -> tuple[int, ...] | None:
        space = getattr(self.model, "observation_space", None)
        return tuple(space.shape) if getattr(space, "shape", None) is not None else None

    @property
    def act_shape(self) -> tuple[int, ...] | None:
        space = getattr(self.model, "action_space", None)
        return tuple(space.shape) if getattr(space, "shape", None) is not None else None

    def _forward(self, obs: np.ndarray) -> np.ndarray:
        return np.asarray(self.model.predict(obs, deterministic=True)[0])

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        return self._invariant(np.asarray(obs))


def as_policy(obj: Any) -> Callable[[np.ndarray], np.ndarray]:
    """Adapt ``obj``: a path (policy file or run), a torch module, an SB3 model, a callable."""
    if isinstance(obj, (str, Path)):
        return load_policy(obj)
    module_names = {c.__module__.split(".")[0] for c in type(obj).__mro__}
    # an SB3 model or SB3 policy (an nn.Module whose forward is not the action: predict is)
    if is_sb3(obj):
        return SB3Policy(obj)
    if "torch" in module_names and hasattr(obj, "parameters"):
        return TorchPolicy(obj)
    if callable(obj):
        return obj
    raise TypeError(
        f"cannot use {type(obj).__name__} as a policy: expected a callable obs -> action"
    )


def is_sb3(obj: Any) -> bool:
    """An SB3 model (``predict`` and ``policy``) or SB3 policy (``predict`` and spaces)."""
    return hasattr(obj, "predict") and (hasattr(obj, "policy") or hasattr(obj, "observation_space"))


def load_policy(path: str | Path) -> Callable[[np.ndarray], np.ndarray]:
    """Load a saved policy: an ``.npz`` MLP file, a training-run directory of ``rrls train``, a
    Stable-Baselines3 ``.zip`` or ``module:attribute`` naming a policy in importable code.

    rrls's own formats (``.npz``, run directories) are read without unpickling. **An SB3 zip and
    ``module:attribute`` run code**: SB3 stores its policy class and spaces with cloudpickle, and
    importing a module executes it — load only files and modules you trust.
    The returned policy's ``metadata`` records where it came from (``path``, ``run_dir``).
    """
    if isinstance(path, str) and is_attribute_reference(path) and not Path(path).exists():
        return load_attribute(path)
    path = Path(path)
    run_dir = None
    if path.suffix == ".zip" and path.is_file():
        return load_sb3(path)
    if path.is_dir():
        from rrls.rundir import POLICY

        if not (path / POLICY).is_file():
            raise FileNotFoundError(f"{path} holds no {POLICY}: not an `rrls train` run")
        run_dir, path = path, path / POLICY
    elif not path.exists():
        raise FileNotFoundError(f"no policy file {path}")
    elif path.suffix != ".npz":
        raise ValueError(
            f"{path}: unknown policy file type (expected an rrls .npz, an `rrls train` run "
            "directory, a Stable-Baselines3 .zip or module:attribute)"
        )
    policy = MLPPolicy.load(path)
    policy.metadata.setdefault("path", str(path))
    if run_dir is not None:
        policy.metadata.setdefault("run_dir", str(run_dir))
    return policy


_ATTRIBUTE = re.compile(r"^[A-Za-z_][\w.]*:[A-Za-z_][\w.]*$")


def is_attribute_reference(text: str) -> bool:
    """Whether ``text`` reads as ``package.module:attribute`` (entry-point syntax)."""
    return bool(_ATTRIBUTE.match(text))


def load_attribute(reference: str) -> Callable[[np.ndarray], np.ndarray]:
    """The policy named by ``module:attribute`` (``pkg.mod:obj`` or ``pkg.mod:obj.attr``),
    adapted with :func:`as_policy`. Importing the module runs its code. A module in the current
    directory is found as ``python -m`` finds it: the directory joins ``sys.path`` (last, so it
    shadows no installed package; worker processes inherit it)."""
    import importlib
    import os
    import sys

    module_name, _, attr = reference.partition(":")
    try:
        try:
            obj: Any = importlib.import_module(module_name)
        except ModuleNotFoundError as err:
            here = os.getcwd()
            top = module_name.partition(".")[0]
            if err.name != top or here in sys.path or "" in sys.path:
                raise
            sys.path.append(here)
            obj = importlib.import_module(module_name)
    except ImportError as err:
        raise ValueError(f"{reference}: cannot import module {module_name!r} ({err})") from None
    for part in attr.split("."):
        if not hasattr(obj, part):
            public = sorted(n for n in dir(obj) if not n.startswith("_"))[:20]
            raise ValueError(
                f"{reference}: {module_name!r} has no attribute {attr!r}; it has: "
                + ", ".join(public)
            )
        obj = getattr(obj, part)
    policy = as_policy(obj)
    meta = getattr(policy, "metadata", None)
    if isinstance(meta, dict):
        meta.setdefault("path", reference)
    return policy


def load_sb3(path: str | Path) -> SB3Policy:
    """A Stable-Baselines3 ``.zip`` (any algorithm with a continuous-action policy: PPO, SAC,
    TD3, ...): the policy rebuilt from the zip's class, spaces and weights, acting
    deterministically. Unpickles the zip's class and spaces (cloudpickle): trusted files only.
    Observation normalisation (``VecNormalize``) is not in the zip and is not applied."""
    try:
        from stable_baselines3.common.save_util import load_from_zip_file
    except ImportError:
        raise ValueError(
            f"{path} is a Stable-Baselines3 zip: loading it needs stable-baselines3 "
            f"({install_hint('sb3')})"
        ) from None
    try:
        data, params, _ = load_from_zip_file(str(path), device="cpu")
        policy = data["policy_class"](
            data["observation_space"],
            data["action_space"],
            lambda _: 0.0,
            **data.get("policy_kwargs", {}),
        )
        policy.load_state_dict(params["policy"])
        policy.set_training_mode(False)
    except Exception as err:  # noqa: BLE001 - any unreadable zip: one line naming it
        raise ValueError(f"{path} is not a loadable Stable-Baselines3 model: {err}") from None
    adapted = SB3Policy(policy)
    adapted.metadata.update(path=str(path), sb3_policy_class=type(policy).__name__)
    return adapted


__all__ = [
    "as_policy",
    "BatchInvariant",
    "BLOCK",
    "is_attribute_reference",
    "is_sb3",
    "load_attribute",
    "load_policy",
    "load_sb3",
    "MLPPolicy",
    "Policy",
    "SB3Policy",
    "TorchPolicy",
]
