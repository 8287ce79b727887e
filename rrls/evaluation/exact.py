"""Matrix products whose every bit is fixed by the operands alone, on any CPU.

Why: a BLAS ``sgemm`` sums each dot product in an order chosen by its kernel, and the kernel
depends on the CPU (AVX2 or AVX-512), the matrix shape and even a row's *position* inside the
kernel's blocks (measured on an AVX2 EPYC: row 63 of a 64-row block differs from the same
observation at row 0 by 4.5e-8). Over 1 000 chaotic steps that last bit becomes another return,
so an evaluation would depend on its batch size, its worker count and the machine.

How (an error-free splitting in the manner of Ozaki et al., "Error-free transformations of
matrix multiplication", Numer. Algorithms 2012): each row of ``x`` and each column of ``w`` is cut
into two slices of ``beta`` significant bits on a fixed grid (the row's or column's own power of
two). A product of two slices, summed over ``k <= 2**(53 - 2*beta)`` terms, is a sum of integers
times one power of two that fits in float64's 53 bits: **every** partial sum is exact, so the
float64 ``dgemm`` of two slices gives the same bits whatever its kernel, blocking or threads. The
three leading slice products are then added in a fixed order, elementwise; what is left out
(``lo @ w_lo`` and the rest below the second slices, ~``2**(-2 beta)`` of a row's scale) is
dropped the same way every time.

Range: each row of ``x`` and each column of ``w`` is first scaled by its own power of two (its
largest entry into [0.5, 1)), so no slice product overflows or underflows, whatever the scale:
rows ×1e300 or of subnormals give the same bits on every kernel (an underflowing product is
where a kernel's fused multiply-add would round otherwise); the result is scaled back with
one rounding (``ldexp``), so it is ±inf only where the product itself leaves float64's range.
What lies below ``2**(-512 - beta)`` of a line's largest entry counts as zero (far below the
``2**(-2 beta)`` dropped anyway). A NaN or inf in a row gives a NaN row.

Cost: three float64 GEMMs instead of one float32 GEMM, plus a few elementwise passes.

``exact_tanh`` is the activation's counterpart: numpy's float64 ``tanh`` is a SIMD routine on
some CPUs (AVX-512) and libm's elsewhere, which differ in the last bits; this one uses only
IEEE-rounded ``+ - * /`` and exact scalings, so its bits are the operands' alone (within 4 ulp
of numpy's; 1 float32 rounding in 10**8 differs from numpy's, measured on normal draws).

>>> import numpy as np
>>> rng = np.random.default_rng(0)
>>> w = rng.normal(size=(16, 4)).astype(np.float32)
>>> x = rng.normal(size=(100, 16)).astype(np.float32)
>>> lin = ExactLinear(w)
>>> bool(np.array_equal(lin(x)[63], lin(x[63:64])[0]))
True
>>> bool(np.allclose(lin(x), x.astype(np.float64) @ w, rtol=1e-12, atol=1e-12))
True
"""

from __future__ import annotations

import math
import threading
from typing import Any

import numpy as np

__all__ = ["ExactLinear", "exact_tanh", "slice_bits"]

#: the second slice's grid is never finer than ``2**(LOWEST - beta)`` of its line's largest
#: entry: what lies below counts as zero (see the module's *Range*)
LOWEST = -512
_LN2_HI = 6.93147180369123816490e-01  # ln 2 split as in fdlibm: k * _LN2_HI is exact
_LN2_LO = 1.90821492927058770002e-10
_INV_LN2 = 1.44269504088896338700e00
_EXPM1 = [1.0 / math.factorial(n) for n in range(1, 16)]  # Taylor to r**15: < 1e-19 on |r|<0.35


def exact_tanh(x: np.ndarray) -> np.ndarray:
    """``tanh`` in float64 from ``+ - * /``, ``rint`` and ``ldexp`` only: the same bits on
    every CPU and numpy SIMD target (``tanh(a) = e / (e + 2)``, ``e = expm1(2a)`` by range
    reduction ``2a = k ln2 + r`` and a Taylor polynomial in ``r``)."""
    x = np.asarray(x, dtype=np.float64)
    nan = np.isnan(x)
    y = 2.0 * np.minimum(np.abs(np.where(nan, 0.0, x)), 22.0)  # tanh(22) is 1.0 in float64
    k = np.rint(y * _INV_LN2)
    r = (y - k * _LN2_HI) - k * _LN2_LO
    p = np.full_like(r, _EXPM1[-1])
    for c in _EXPM1[-2::-1]:  # Horner, in place: p = c + r * p
        np.multiply(p, r, out=p)
        np.add(p, c, out=p)
    np.multiply(p, r, out=p)
    ki = k.astype(np.int64)
    e = np.ldexp(p, ki) + (np.ldexp(1.0, ki) - 1.0)  # expm1(y) = 2**k expm1(r) + 2**k - 1
    out = np.copysign(e / (e + 2.0), x)
    out[nan] = np.nan
    return out


def slice_bits(k: int) -> int:
    """Bits per slice so that a sum of ``k`` slice products is exact in float64."""
    if k < 1:
        raise ValueError(f"a product needs at least one term, got k={k}")
    return (53 - int(np.ceil(np.log2(k)))) // 2 if k > 1 else 26


def _slice(rest: np.ndarray, e: Any, beta: int, part: np.ndarray) -> None:
    """``part`` = ``rest`` rounded to a multiple of ``2**(e - beta)``; ``rest -= part`` (exact:
    ``part`` is ``rest`` rounded to a coarser grid)."""
    # adding 1.5 * 2**(52 + e - beta) rounds to a multiple of 2**(e - beta), exactly once
    sigma = np.ldexp(1.5, 52 + e - beta)
    np.add(rest, sigma, out=part)
    np.subtract(part, sigma, out=part)
    np.subtract(rest, part, out=rest)


def _split_into(rest: np.ndarray, axis: int, beta: int, hi: np.ndarray, lo: np.ndarray) -> None:
    """Cut a normalised ``rest`` (``_normalise``: each line's largest entry in [0.5, 1); float64,
    overwritten) into ``hi + lo + rest``, ``beta`` bits each: ``hi`` on the grid ``2**-beta``,
    ``lo`` on the grid of the largest entry left, never finer than ``2**(LOWEST - beta)`` (so
    the rounding constant stays a normal number)."""
    _slice(rest, 0, beta, hi)
    np.abs(rest, out=lo)
    e = np.frexp(lo.max(axis=axis, keepdims=True))[1]  # an all-zero line keeps e = 0
    np.maximum(e, LOWEST, out=e)
    _slice(rest, e, beta, lo)


def _normalise(a: np.ndarray, axis: int, largest: np.ndarray | None = None) -> np.ndarray:
    """Scale ``a`` (float64, in place) by a power of two per line along ``axis``, its largest
    entry (``largest``, if known) into [0.5, 1); returns the exponents."""
    if largest is None:
        largest = np.abs(a).max(axis=axis, keepdims=True)
    e = np.frexp(largest)[1]  # an all-zero line keeps e = 0
    _times_power_of_two(a, -e)
    return e


def _times_power_of_two(a: np.ndarray, *exponents: np.ndarray) -> None:
    """``a *= 2**sum(exponents)`` in place (broadcast), rounded once, as ``np.ldexp``: by
    multiplying with the exact factor ``2**e1 * 2**e2 ...`` where every power involved and
    their product are normal numbers (a multiplication is ~20x faster than ``ldexp``), else by
    ``ldexp`` itself."""
    lows, highs = [int(e.min()) for e in exponents], [int(e.max()) for e in exponents]
    if all(-1022 <= b <= 1023 for b in (*lows, *highs, sum(lows), sum(highs))):
        factor = np.ldexp(1.0, exponents[0])
        for e in exponents[1:]:
            factor = factor * np.ldexp(1.0, e)
        np.multiply(a, factor, out=a)
    else:
        np.ldexp(a, sum(exponents[1:], exponents[0]), out=a)


class ExactLinear:
    """``x @ w`` (``x``: ``[B, k]``, ``w``: ``[k, n]``) as float64, the same bits on any CPU
    and for any batch: row ``i`` of the result depends on row ``i`` of ``x`` only."""

    def __init__(self, w: np.ndarray) -> None:
        w = np.array(w, dtype=np.float64)  # a copy: split in place below
        if w.ndim != 2:
            raise ValueError(f"expected a [k, n] weight matrix, got shape {w.shape}")
        self.k, self.n = w.shape
        self.beta = slice_bits(self.k)
        self.e_col = _normalise(w, 0)  # w's columns scaled into [0.5, 1) by powers of two
        hi, lo = np.empty_like(w), np.empty_like(w)
        _split_into(w, 0, self.beta, hi, lo)
        self.w_hi = hi
        self.w_both = np.ascontiguousarray(np.concatenate([hi, lo], axis=1))  # [k, 2n]
        # Work buffers by batch size: fresh multi-megabyte arrays page-fault on first touch,
        # which cost ~5x the arithmetic (measured, B = 1000, k = 256). One set per thread: a
        # policy called from several threads at once must not share them.
        self._local = threading.local()

    def _buffers(self, b: int) -> tuple[np.ndarray, ...]:
        scratch: dict[int, tuple[np.ndarray, ...]] = self._local.__dict__.setdefault("s", {})
        if b not in scratch:
            if len(scratch) >= 4:
                scratch.pop(next(iter(scratch)))
            k, n = self.k, self.n
            scratch[b] = (*(np.empty((b, k)) for _ in range(3)), np.empty((b, 2 * n)))
        return scratch[b]

    def __getstate__(self) -> dict:
        state = self.__dict__.copy()
        del state["_local"]  # work buffers are not pickled: each process makes its own
        return state

    def __setstate__(self, state: dict) -> None:
        self.__dict__.update(state)
        self._local = threading.local()

    def __call__(self, x: np.ndarray) -> np.ndarray:
        x = np.asarray(x)
        if x.ndim != 2 or x.shape[1] != self.k:
            raise ValueError(f"expected inputs of shape (B, {self.k}), got {x.shape}")
        n = self.n
        rest, hi, lo, p = self._buffers(len(x))
        np.copyto(rest, x)
        with np.errstate(invalid="ignore", over="ignore"):
            largest = np.abs(rest, out=hi).max(axis=1, keepdims=True)
            bad = ~np.isfinite(largest[:, 0])
            if bad.any():  # a NaN or inf input gives a NaN row, as a plain product would
                rest[bad] = 0.0
                largest[bad] = 0.0
            e_row = _normalise(rest, 1, largest)
            _split_into(rest, 1, self.beta, hi, lo)
            np.matmul(hi, self.w_both, out=p)  # each product exact, whatever the kernel
            out = p[:, :n] + p[:, n:]
            np.matmul(lo, self.w_hi, out=p[:, :n])
            out += p[:, :n]  # lo @ w_lo (below 2**(-2 beta) of the line's scale): dropped
            _times_power_of_two(out, e_row, self.e_col)  # back to scale: one rounding
        if bad.any():
            out[bad] = np.nan
        return out
