"""Uncertainty sets: boxes over named physical parameters.

An :class:`UncertaintySet` is what the paper calls Omega: the box over which domain randomization
samples, the adversary acts and the evaluation mesh is laid. It is a small immutable value
object; points are ``dict[str, float]`` (what ``set_params`` takes) or arrays ordered like
``names`` (what samplers and optimisers want).

>>> import numpy as np
>>> from rrls.uncertainty import UncertaintySet
>>> box = UncertaintySet.from_bounds({"worldfriction": (0.1, 3.0), "torsomass": (0.1, 3.0)})
>>> box.dim
2
>>> box.mesh(3)[-1].tolist()  # the mesh reaches both bounds
[3.0, 3.0]
>>> point = box.sample(np.random.default_rng(0))
>>> box.contains(point)
True
>>> box.normalize([0.1, 3.0]).tolist()
[-1.0, 1.0]
"""

from __future__ import annotations

import itertools
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from rrls.schema import Schema, SchemaError, array, number, string

#: the most points a mesh may have: 10**6 points of 5 episodes of 1 000 steps is already
#: 5 * 10**9 env steps; beyond it an evaluation could not finish, and the arrays alone fill memory
MAX_MESH_POINTS = 1_000_000

ArrayLike = Sequence[float] | np.ndarray
Point = Mapping[str, float] | ArrayLike


@dataclass(frozen=True, eq=False)
class UncertaintySet:
    """A box ``low <= x <= high`` over the parameters ``names``.

    ``nominal`` is the unmodified environment's point (``None`` when unknown); ``label`` names
    the set in reprs and result files (e.g. ``"hopper/3d"``); ``family`` is the env family whose
    parameters it names (``"robust"``: masses and friction, ``"force"``: external forces;
    ``None`` when unknown: :func:`rrls.envs.resolve` finds it from the task's parameter table).
    A zero-dimensional set (no names) is the unmodified model itself: its mesh is one empty point.
    """

    names: tuple[str, ...]
    low: np.ndarray
    high: np.ndarray
    nominal: np.ndarray | None = None
    label: str = ""
    family: str | None = None

    def __post_init__(self) -> None:
        names = tuple(self.names)
        low = np.array(self.low, dtype=np.float64).reshape(-1)
        high = np.array(self.high, dtype=np.float64).reshape(-1)
        if not all(isinstance(n, str) and n for n in names):
            raise ValueError(f"parameter names must be non-empty strings, got {names!r}")
        if self.family not in (None, "robust", "force"):
            raise ValueError(f"family must be 'robust', 'force' or None, got {self.family!r}")
        if len(set(names)) != len(names):
            raise ValueError(f"duplicate parameter names in {names}")
        if low.shape != (len(names),) or high.shape != (len(names),):
            raise ValueError(
                f"low and high need one value per name ({len(names)}), "
                f"got shapes {low.shape} and {high.shape}"
            )
        if not (np.all(np.isfinite(low)) and np.all(np.isfinite(high))):
            bad = [n for n, lo, hi in zip(names, low, high) if not np.isfinite([lo, hi]).all()]
            raise ValueError(
                f"bounds must be finite: {', '.join(bad)} got "
                + ", ".join(f"[{lo}, {hi}]" for n, lo, hi in zip(names, low, high) if n in bad)
            )
        bad = [n for n, lo, hi in zip(names, low, high) if lo > hi]
        if bad:
            raise ValueError(f"low > high for {bad}")
        low.flags.writeable = False
        high.flags.writeable = False
        object.__setattr__(self, "names", names)
        object.__setattr__(self, "low", low)
        object.__setattr__(self, "high", high)
        if self.nominal is not None:
            nominal = np.array(self.nominal, dtype=np.float64).reshape(-1)
            if nominal.shape != low.shape:
                raise ValueError(f"nominal needs {len(names)} values, got {nominal.shape}")
            nominal.flags.writeable = False
            object.__setattr__(self, "nominal", nominal)

    # -- construction -------------------------------------------------------------------------
    @classmethod
    def from_bounds(
        cls,
        bounds: Mapping[str, Sequence[float]],
        nominal: Mapping[str, float] | None = None,
        label: str = "",
        family: str | None = None,
    ) -> UncertaintySet:
        """From the original code's ``{name: [low, high]}`` dicts (``...ParamsBound.X.value``)."""
        if isinstance(bounds, UncertaintySet):
            return bounds
        if not isinstance(bounds, Mapping):
            raise TypeError(
                f"bounds must be a {{name: [low, high]}} mapping or an UncertaintySet, "
                f"got {type(bounds).__name__}"
            )
        names = tuple(bounds)
        for n in names:
            if isinstance(bounds[n], (str, bytes)) or not hasattr(bounds[n], "__len__"):
                raise ValueError(f"bounds of {n!r} must be [low, high], got {bounds[n]!r}")
            if len(bounds[n]) != 2:
                raise ValueError(f"bounds of {n!r} must be [low, high], got {bounds[n]!r}")
        try:
            low = [float(bounds[n][0]) for n in names]
            high = [float(bounds[n][1]) for n in names]
        except (TypeError, ValueError) as err:
            raise ValueError(f"bounds must be numbers: {err}") from None
        nom = None if nominal is None else [float(nominal[n]) for n in names]
        return cls(
            names,
            np.array(low, dtype=np.float64).reshape(-1),
            np.array(high, dtype=np.float64).reshape(-1),
            None if nom is None else np.array(nom),
            label,
            family,
        )

    def as_bounds(self) -> dict[str, list[float]]:
        """The original code's ``{name: [low, high]}`` form."""
        return {n: [float(lo), float(hi)] for n, lo, hi in zip(self.names, self.low, self.high)}

    # -- conversions --------------------------------------------------------------------------
    @property
    def dim(self) -> int:
        return len(self.names)

    def to_array(self, point: Point) -> np.ndarray:
        """``point`` as an array ordered like ``names`` (a dict must name every parameter)."""
        if isinstance(point, Mapping):
            missing = [n for n in self.names if n not in point]
            extra = [k for k in point if k not in self.names]
            if missing or extra:
                raise ValueError(
                    f"point must name exactly {list(self.names)}; missing {missing}, extra {extra}"
                )
            return np.array([float(point[n]) for n in self.names])
        arr = np.asarray(point, dtype=np.float64)
        if arr.shape[-1:] != (self.dim,):
            raise ValueError(f"expected {self.dim} values per point, got shape {arr.shape}")
        return arr

    def to_dict(self, x: ArrayLike) -> dict[str, float]:
        """One point as ``{name: value}``, ready for ``env.set_params(**point)``."""
        x = self.to_array(x)
        if x.ndim != 1:
            raise ValueError(f"to_dict takes one point, got shape {x.shape}")
        return {n: float(v) for n, v in zip(self.names, x)}

    # -- geometry -----------------------------------------------------------------------------
    def sample(
        self, rng: np.random.Generator, n: int | None = None
    ) -> dict[str, float] | np.ndarray:
        """Uniform draw(s) from ``rng``: a dict for ``n=None``, else an ``(n, dim)`` array."""
        if not isinstance(rng, np.random.Generator):
            raise TypeError(f"rng must be a numpy.random.Generator, got {type(rng).__name__}")
        if n is None:
            return self.to_dict(rng.uniform(self.low, self.high))
        return rng.uniform(self.low, self.high, size=(n, self.dim))

    def mesh_size(self, n: int) -> int:
        """The number of points of a mesh of ``n`` per dimension (about ``n ** dim``: the
        paper's ``np.arange`` may add one per axis), refused above ``MAX_MESH_POINTS`` before
        any array is made (one line with the largest ``n`` allowed here)."""
        if isinstance(n, bool) or int(n) != n or n < 1:
            raise ValueError(f"mesh size must be a positive integer, got {n!r}")
        n = int(n)
        if n**self.dim > MAX_MESH_POINTS:
            raise ValueError(
                f"a mesh of {n} per dimension over {self.dim} dimension(s) is {n**self.dim:,} "
                f"points; at most {MAX_MESH_POINTS:,} (a mesh of "
                f"{int(MAX_MESH_POINTS ** (1 / max(self.dim, 1)) + 1e-9)} here)"
            )
        return n**self.dim

    def mesh(self, n: int, endpoint: bool = True) -> np.ndarray:
        """The ``n ** dim`` points of a uniform grid, shape ``(n ** dim, dim)``.

        ``endpoint=True`` includes both bounds (``np.linspace``, as the M2TD3 authors evaluate);
        ``endpoint=False`` reproduces the original RRLS code (``np.arange(low, high, step)``
        with ``step = (high - low) / n``), which never reaches the upper bound. The first
        parameter varies slowest (``itertools.product`` order).
        """
        n = self.mesh_size(n) and int(n)
        if endpoint:
            axes = [np.linspace(lo, hi, n) for lo, hi in zip(self.low, self.high)]
        else:
            # exactly the original's call (float rounding can give n + 1 points on an axis)
            axes = [
                np.arange(lo, hi, (hi - lo) / n) if hi > lo else np.array([lo])
                for lo, hi in zip(self.low, self.high)
            ]
        if self.dim == 0:
            return np.zeros((1, 0))  # the one point of the unmodified model
        return np.array(list(itertools.product(*axes)), dtype=np.float64).reshape(-1, self.dim)

    def normalize(self, x: Point) -> np.ndarray:
        """Map points of the box to ``[-1, 1]`` (a degenerate axis maps to 0)."""
        x = self.to_array(x)
        span = self.high - self.low
        safe = np.where(span > 0, span, 1.0)
        return np.where(span > 0, 2.0 * (x - self.low) / safe - 1.0, 0.0)

    def denormalize(self, z: ArrayLike) -> np.ndarray:
        """Map ``[-1, 1]`` to the box (the adversary's action -> parameters)."""
        z = np.asarray(z, dtype=np.float64)
        if z.shape[-1:] != (self.dim,):
            raise ValueError(f"expected {self.dim} values per point, got shape {z.shape}")
        return self.low + (z + 1.0) * 0.5 * (self.high - self.low)

    def clip(self, x: Point) -> np.ndarray:
        return np.clip(self.to_array(x), self.low, self.high)

    def contains(self, point: Point, atol: float = 0.0) -> bool | np.ndarray:
        """Whether the point(s) lie in the box (an array of bools for a batch)."""
        x = self.to_array(point)
        inside = np.all((x >= self.low - atol) & (x <= self.high + atol), axis=-1)
        return bool(inside) if np.ndim(inside) == 0 else inside

    # -- misc ---------------------------------------------------------------------------------
    def __eq__(self, other: object) -> bool:
        if not isinstance(other, UncertaintySet):
            return NotImplemented
        return (
            self.names == other.names
            and np.array_equal(self.low, other.low)
            and np.array_equal(self.high, other.high)
        )

    def __hash__(self) -> int:
        return hash((self.names, self.low.tobytes(), self.high.tobytes()))

    def __len__(self) -> int:
        return self.dim

    def __repr__(self) -> str:
        rows = ", ".join(
            f"{n}=[{lo:g}, {hi:g}]" for n, lo, hi in zip(self.names, self.low, self.high)
        )
        label = f"{self.label!r}, " if self.label else ""
        return f"UncertaintySet({label}{rows})"


#: the smallest training part an interpolation split may leave (a share of the set's volume):
#: below it, rejection sampling would take millions of draws per episode
_MIN_TRAIN_FRACTION = 1e-6
#: draws ``Split.sample_train`` tries before refusing (unreachable above the minimum share)
_MAX_REJECTIONS = 100_000_000


@dataclass(frozen=True, eq=False)
class Split:
    """A train/test split of a set, declared as data: rrls's own interpolation/extrapolation
    split, inspired by the generalisation protocols of contextual RL (CARL's code has no such
    split: its train and test contexts are lists the user samples).

    ``region`` is a box inside ``box`` (same names). ``kind="interpolation"``: the region is a
    held-out interior, so training covers the set minus the region and testing the region;
    ``kind="extrapolation"``: training covers the region (an inner box) and testing the outer
    shell. "In distribution" means "in the training part"; the region is closed, and every point
    is exactly one of in-distribution or out-of-distribution (the two masks partition any mesh).

    >>> from rrls.uncertainty import Split, UncertaintySet
    >>> box = UncertaintySet.from_bounds({"torsomass": (1.0, 5.0)})
    >>> split = Split.extrapolation(box, inner=0.5)  # train on [2, 4], test outside it
    >>> split.region.as_bounds()
    {'torsomass': [2.0, 4.0]}
    >>> split.in_distribution(box.mesh(5)).tolist()
    [False, True, True, True, False]
    """

    kind: str
    box: UncertaintySet
    region: UncertaintySet

    KINDS = ("interpolation", "extrapolation")

    def __post_init__(self) -> None:
        if self.kind not in self.KINDS:
            raise ValueError(
                f"split kind must be one of {', '.join(self.KINDS)}, got {self.kind!r}"
            )
        if self.region.names != self.box.names:
            raise ValueError(
                f"the split's region must name the set's parameters {list(self.box.names)}, "
                f"got {list(self.region.names)}"
            )
        if self.box.dim == 0:
            raise ValueError("an empty set cannot be split")
        outside = [
            n
            for n, lo, hi, rlo, rhi in zip(
                self.box.names, self.box.low, self.box.high, self.region.low, self.region.high
            )
            if rlo < lo or rhi > hi
        ]
        if outside:
            raise ValueError(f"the split's region leaves the set along {outside}")
        if self.kind == "interpolation" and self.train_fraction() < _MIN_TRAIN_FRACTION:
            # nothing (or a sliver) left to train on: sample_train would never return
            raise ValueError(
                f"the split's training part is empty: the held-out region "
                f"{self.region.as_bounds()} covers the whole set {self.box.as_bounds()} (or "
                f"all but under {_MIN_TRAIN_FRACTION:g} of it); hold out a smaller region (a "
                "fraction of each axis in (0, 1))"
            )

    def train_fraction(self) -> float:
        """The training part's share of the set's volume (flat axes count as full)."""
        width = self.box.high - self.box.low
        held = np.where(
            width > 0, (self.region.high - self.region.low) / np.where(width > 0, width, 1), 1.0
        )
        inner = float(np.prod(held))
        return inner if self.kind == "extrapolation" else 1.0 - inner

    @classmethod
    def _region(cls, box: UncertaintySet, inner: float | Mapping[str, Sequence[float]]) -> Any:
        if isinstance(inner, Mapping):
            region = UncertaintySet.from_bounds(inner)
            if set(region.names) != set(box.names):
                raise ValueError(
                    f"the region must give bounds for exactly {list(box.names)}, "
                    f"got {list(region.names)}"
                )
            return UncertaintySet(
                box.names,
                [region.as_bounds()[n][0] for n in box.names],
                [region.as_bounds()[n][1] for n in box.names],
            )
        if (
            isinstance(inner, bool)
            or not isinstance(inner, (int, float, np.integer, np.floating))
            or not 0.0 < float(inner) < 1.0
        ):
            raise ValueError(
                f"the region's size must be a fraction of each axis in (0, 1) or a "
                f"{{name: [low, high]}} mapping, got {inner!r}"
            )
        centre, half = (box.low + box.high) / 2, (box.high - box.low) * float(inner) / 2
        return UncertaintySet(box.names, centre - half, centre + half)

    @classmethod
    def interpolation(
        cls, box: UncertaintySet, hold_out: float | Mapping[str, Sequence[float]] = 0.5
    ) -> Split:
        """Hold out an interior region (``hold_out``: a centred fraction of each axis, or bounds)
        for testing; train on the rest of the set."""
        return cls("interpolation", box, cls._region(box, hold_out))

    @classmethod
    def extrapolation(
        cls, box: UncertaintySet, inner: float | Mapping[str, Sequence[float]] = 0.5
    ) -> Split:
        """Train on an inner box (``inner``: a centred fraction of each axis, or bounds); test on
        the outer shell of the set."""
        return cls("extrapolation", box, cls._region(box, inner))

    @classmethod
    def parse(cls, box: UncertaintySet, text: str) -> Split:
        """A split from its command-line form, ``KIND[:F]`` (``extrapolation:0.5``: train on
        the centred half of each axis; ``interpolation:0.5``: hold it out); F defaults to 0.5."""
        kind, _, size = str(text).strip().lower().partition(":")
        if kind not in cls.KINDS:
            raise ValueError(
                f"split {text!r}: the kind must be one of {', '.join(cls.KINDS)} "
                "(KIND or KIND:F, F a fraction of each axis in (0, 1))"
            )
        try:
            fraction = float(size) if size else 0.5
        except ValueError:
            raise ValueError(
                f"split {text!r}: F must be a fraction of each axis in (0, 1), got {size!r}"
            ) from None
        return getattr(cls, kind)(box, fraction)

    def in_distribution(self, points: Point) -> np.ndarray | bool:
        """Whether the point(s) lie in the training part of the split."""
        inside = np.asarray(self.region.contains(self.box.to_array(points)), dtype=bool)
        out = np.logical_not(inside) if self.kind == "interpolation" else inside
        return bool(out) if out.ndim == 0 else out

    def out_of_distribution(self, points: Point) -> np.ndarray | bool:
        """Whether the point(s) lie in the test part: exactly the complement."""
        out = np.logical_not(self.in_distribution(points))
        return bool(out) if np.ndim(out) == 0 else out

    @property
    def train_set(self) -> UncertaintySet | None:
        """The training part as a box (extrapolation), None where it is not one."""
        return self.region if self.kind == "extrapolation" else None

    def sample_train(self, box: UncertaintySet, rng: np.random.Generator) -> dict[str, float]:
        """One uniform draw from the training part; a ``DomainRandomization`` ``randomize_fn``:
        ``DomainRandomization(env, split.box, randomize_fn=split.sample_train)``."""
        if self.kind == "extrapolation":
            return self.region.sample(rng)
        for _ in range(_MAX_REJECTIONS):  # rejection: the held-out interior is a strict part
            x = rng.uniform(self.box.low, self.box.high)
            if self.in_distribution(x):
                return self.box.to_dict(x)
        raise ValueError(  # a sliver of a training part: say so rather than loop for hours
            f"no draw in the training part of {self!r} after {_MAX_REJECTIONS} tries: the "
            "held-out region covers almost the whole set; hold out a smaller region"
        )

    def to_json(self) -> dict[str, Any]:
        return {
            "kind": self.kind,
            "names": list(self.box.names),
            "low": self.box.low.tolist(),
            "high": self.box.high.tolist(),
            "region_low": self.region.low.tolist(),
            "region_high": self.region.high.tolist(),
        }

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> Split:
        check_box(data, SPLIT_SCHEMA, "split")
        names = tuple(data["names"])
        return cls(
            data["kind"],
            UncertaintySet(names, data["low"], data["high"]),
            UncertaintySet(names, data["region_low"], data["region_high"]),
        )

    def __repr__(self) -> str:
        return f"Split({self.kind}, region={self.region!r} of {self.box!r})"

    def __eq__(self, other: object) -> bool:  # by value: a split read back equals its source
        if not isinstance(other, Split):
            return NotImplemented
        return (self.kind, self.box, self.region) == (other.kind, other.box, other.region)

    def __hash__(self) -> int:
        return hash((self.kind, self.box, self.region))


#: an ``UncertaintySet`` as JSON (a protocol's own box): names a list of strings (a string was
#: read as one name per letter), bounds finite numbers (``"1"`` and ``true`` were read as 1.0)
BOX_SCHEMA = Schema(
    {
        "names": array(string(), required=True),
        "low": array(number(), required=True),
        "high": array(number(), required=True),
        "nominal": array(number(), null=True),
        "label": string(),
        "family": string(choices=("robust", "force"), null=True),
    }
)
#: a ``Split`` as JSON (``Split.to_json``), typed as a box is
SPLIT_SCHEMA = Schema(
    {
        "kind": string(required=True),
        "names": array(string(), required=True),
        **{key: array(number(), required=True) for key in ("low", "high")},
        **{key: array(number(), required=True) for key in ("region_low", "region_high")},
    }
)


def check_box(data: Any, schema: Schema, where: str, path: str = "") -> None:
    """``data`` (a box's or a split's JSON) against ``schema``, with one bound per name in each
    list of bounds; otherwise a one-line ``SchemaError`` naming ``where``, the field and value."""
    schema.check(data, where, path)
    n = len(data["names"])
    for key in ("low", "high", "nominal", "region_low", "region_high"):
        value = data.get(key)
        if value is not None and len(value) != n:
            field = f"{path}.{key}" if path else key
            raise SchemaError(
                f"{where}: field {field!r} holds {len(value)} values; valid: one per name ({n})"
            )


__all__ = [
    "BOX_SCHEMA",
    "MAX_MESH_POINTS",
    "SPLIT_SCHEMA",
    "ArrayLike",
    "Point",
    "Split",
    "UncertaintySet",
    "check_box",
]
