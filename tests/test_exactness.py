"""The same bits on any CPU: rrls's own policy and products do not depend on the BLAS kernel.

``.ci/run`` runs every ``exactness`` test three times: with the machine's own kernels, with
numpy's and OpenBLAS's AVX-512 paths disabled, and on baseline SSE kernels, so a result that
depends on a kernel's blocking fails CI on any machine, not only on the CPU it was written on.
The refusals here compute no product, so no kernel can change them: they are not marked and run
once.
"""

from __future__ import annotations

import hashlib

import numpy as np
import pytest

from rrls.evaluation.exact import ExactLinear, exact_tanh, slice_bits
from rrls.evaluation.policies import MLPPolicy

# sha256 of a fixed random 17-256-256-6 MLPPolicy's float32 actions on 300 fixed observations,
# measured on AMD EPYC (AVX2) with numpy's X86_V3 / OpenBLAS Haswell kernels, and equal there
# with baseline X86_V2 / Sandybridge and Nehalem kernels. A plain float32 sgemm forward gives
# a938b14fa4d6af0b and 78b880e4a7d4d47b on the first and last of those (the test can fail).
GOLDEN = "fa460b1c3f9d1e23"


@pytest.mark.exactness
def test_mlp_policy_actions_are_the_same_bits_on_any_cpu():
    policy = MLPPolicy.random(17, 6, (256, 256), seed=7)
    obs = np.random.default_rng(3).normal(scale=3.0, size=(300, 17))
    actions = np.ascontiguousarray(policy(obs))
    assert actions.dtype == np.float32
    assert hashlib.sha256(actions.tobytes()).hexdigest()[:16] == GOLDEN


@pytest.mark.exactness
@pytest.mark.parametrize("batch", [1, 7, 64, 65, 300])
def test_a_row_depends_on_its_observation_alone(batch):
    policy = MLPPolicy.random(11, 3, (64, 64), seed=1)
    obs = np.random.default_rng(batch).normal(size=(batch, 11))
    rows = policy(obs)
    for i in {0, batch // 2, batch - 1}:
        alone = policy(obs[i : i + 1])[0]
        assert np.array_equal(rows[i], alone)
        # at any position of another batch: the same bits
        other = np.random.default_rng(99).normal(size=(130, 11))
        other[-1] = obs[i]
        assert np.array_equal(policy(other)[-1], alone)


@pytest.mark.exactness
@pytest.mark.parametrize("k", [1, 3, 11, 256, 376, 1024])
def test_exact_linear_is_order_free_and_accurate(k):
    rng = np.random.default_rng(k)
    w = rng.normal(size=(k, 5)) * np.exp(rng.normal(scale=3, size=(k, 1)))  # wide exponents
    x = rng.normal(size=(40, k)).astype(np.float32)
    lin = ExactLinear(w)
    out = lin(x)
    ref = x.astype(np.float64) @ w
    # what is dropped (lo @ w_lo, the rests): below k + 2 terms of 2**-2beta of the line scales
    scale = np.abs(x).max(axis=1, keepdims=True) * np.abs(w).max(axis=0)
    assert np.all(np.abs(out - ref) <= 4 * (k + 2) * scale * 2.0 ** (-2 * slice_bits(k)))
    # the order of the rows and of the terms does not change a bit
    perm = rng.permutation(k)
    assert np.array_equal(ExactLinear(w[perm])(x[:, perm]), out)
    assert np.array_equal(lin(x[::-1])[::-1], out)


@pytest.mark.exactness
def test_exact_linear_non_finite_rows_are_nan_and_do_not_spread():
    lin = ExactLinear(np.ones((3, 2)))
    x = np.array([[1.0, 2.0, 3.0], [np.inf, 0.0, 0.0], [np.nan, 1.0, 1.0], [0.0, 0.0, 0.0]])
    out = lin(x)
    assert np.array_equal(out[0], [6.0, 6.0]) and np.array_equal(out[3], [0.0, 0.0])
    assert np.isnan(out[1:3]).all()


def test_exact_linear_refuses_bad_shapes():
    with pytest.raises(ValueError, match=r"\[k, n\]"):
        ExactLinear(np.ones(3))
    with pytest.raises(ValueError, match=r"shape \(B, 3\)"):
        ExactLinear(np.ones((3, 2)))(np.ones((2, 4)))


def _digest(a: np.ndarray) -> str:
    return hashlib.sha256(np.ascontiguousarray(a).tobytes()).hexdigest()[:16]


# The float64 policy and the range edges, measured on AMD EPYC (AVX2) with numpy X86_V3 and
# baseline X86_V2, OpenBLAS Haswell, Sandybridge and Nehalem: equal on all. With numpy's own
# float64 tanh the policy gave c84acf45d33b1d79 (X86_V3) and 90c1d8610906d931 (X86_V2), and the
# product without its per-line scaling 0041bebbf5086f08 / 763ebac1cd29004c for weights x1e-305
# (subnormal slice products, rounded differently by fused and unfused kernels): the test can fail.
GOLDEN_F64 = "26c3b1dc2ef4f015"
GOLDEN_EDGES = ("b8cbb8685717c2b6", "ea2012f5d174c039", "3d0a85827d528dc6")
GOLDEN_TANH = "79120c2eb68b5fc9"


@pytest.mark.exactness
def test_float64_mlp_policy_is_the_same_bits_on_any_cpu():
    policy = MLPPolicy.random(17, 6, (256, 256), seed=7, dtype=np.float64)
    obs = np.random.default_rng(3).normal(scale=3.0, size=(300, 17))
    actions = policy(obs)
    assert actions.dtype == np.float64
    assert _digest(actions) == GOLDEN_F64


@pytest.mark.exactness
def test_exact_linear_huge_and_subnormal_lines_are_the_same_bits_on_any_cpu():
    rng = np.random.default_rng(5)
    w, x = rng.normal(size=(256, 8)), rng.normal(size=(64, 256))
    scales = np.array([1e300, 1e-300, 1e-310, 1e-318, 1.0, 2.0**-1074 * 3, 1e-200, 1e200])
    xs = x * np.repeat(scales, 8)[:, None]
    edges = (ExactLinear(w)(xs), ExactLinear(w * 1e-305)(x), ExactLinear(w * 1e290)(x * 1e15))
    assert tuple(_digest(e) for e in edges) == GOLDEN_EDGES
    # huge lines stay finite and accurate where the product is (x1e300 was NaN before scaling)
    for out, ref in ((edges[0][:8], xs[:8] @ w), (edges[2], x * 1e15 @ (w * 1e290))):
        assert np.isfinite(out).all()
        assert np.allclose(out, ref, rtol=1e-9, atol=0)
    assert np.allclose(edges[0][8:16], xs[8:16] @ w, rtol=1e-9, atol=0)  # ×1e-300: normal
    assert np.array_equal(ExactLinear(w)(xs[::-1])[::-1], edges[0])  # order-free there too


def test_a_policy_file_with_non_finite_weights_is_refused(tmp_path):
    policy = MLPPolicy.random(3, 2, (4,), seed=0)
    policy.weights[0][1, 0] = np.nan
    policy.save(tmp_path / "p.npz")
    with pytest.raises(ValueError, match="NaN or inf"):
        MLPPolicy.load(tmp_path / "p.npz")


@pytest.mark.exactness
def test_exact_tanh_is_the_same_bits_on_any_cpu_and_within_4_ulp_of_numpy():
    t = np.random.default_rng(9).normal(scale=4, size=100_000)
    out = exact_tanh(t)
    assert _digest(out) == GOLDEN_TANH
    ulp = np.abs(out - np.tanh(t)) / np.spacing(np.abs(np.tanh(t)))
    assert ulp.max() <= 4
    edge = np.array([0.0, -0.0, 5e-324, -1e-300, 25.0, -1e308, np.inf, -np.inf, np.nan])
    got = exact_tanh(edge)
    want = np.array([0.0, -0.0, 5e-324, -1e-300, 1.0, -1.0, 1.0, -1.0, np.nan])
    assert np.array_equal(got, want, equal_nan=True)
    assert np.array_equal(np.signbit(got[:2]), [False, True])
