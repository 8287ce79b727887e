"""A shipped policy is safe to call from several threads at once: each thread has its own work
buffers, so concurrent calls give the actions a lone call gives, bit for bit."""

from __future__ import annotations

import pickle
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest

from rrls.evaluation.policies import MLPPolicy


@pytest.mark.e2e
def test_concurrent_calls_give_the_lone_calls_bits():
    policy = MLPPolicy.random(11, 3, hidden=(256, 256), seed=0)
    rng = np.random.default_rng(1)
    # the same batch sizes in every thread: the case that shared one buffer set before
    batches = [rng.normal(size=(64, 11)) for _ in range(240)]
    alone = [policy(b) for b in batches]
    with ThreadPoolExecutor(4) as pool:
        together = list(pool.map(policy, batches))
    wrong = sum(not np.array_equal(a, b) for a, b in zip(alone, together))
    assert wrong == 0, f"{wrong} of {len(batches)} concurrent calls differ"


def test_a_pickled_policy_carries_no_work_buffers_and_still_acts():
    policy = MLPPolicy.random(11, 3, seed=0)
    obs = np.random.default_rng(2).normal(size=(500, 11))
    before = policy(obs)  # fills this thread's buffers
    copy = pickle.loads(pickle.dumps(policy))
    assert len(pickle.dumps(policy)) < 2_000_000  # weights, not 500-row buffers
    np.testing.assert_array_equal(copy(obs), before)
