"""A policy is prepared once at the door (adapted, checked, probed, fingerprinted) and every
evaluation takes the prepared object as it is; the worst-case search takes a ``Protocol``."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from rrls.evaluation import (
    PreparedPolicy,
    Protocol,
    evaluate,
    evaluate_dynamic,
    policies,
    prepare,
    search_worst_case,
)
from rrls.evaluation import prepared as prepare_module

W = np.random.default_rng(1).normal(size=(11, 3)) * 0.3


def linear(obs):  # row by row, no BLAS: the same actions whatever the batch
    return np.tanh((np.asarray(obs)[:, :, None] * W).sum(axis=1))


@pytest.fixture
def probes(monkeypatch):
    """Counts the batch-invariance probes and the protagonist's adaptations."""
    counts = {"probe": 0, "adapt": 0}
    probe, adapt = prepare_module.is_batch_invariant, prepare_module.as_policy

    def counted_probe(*args, **kw):
        counts["probe"] += 1
        return probe(*args, **kw)

    def counted_adapt(obj):
        counts["adapt"] += obj is linear or isinstance(obj, PreparedPolicy)  # not the adversary
        return adapt(obj)

    monkeypatch.setattr(prepare_module, "is_batch_invariant", counted_probe)
    monkeypatch.setattr(prepare_module, "as_policy", counted_adapt)
    monkeypatch.setattr(policies, "as_policy", counted_adapt)  # what evaluate imports
    return counts


def test_a_prepared_policy_is_probed_once_for_every_evaluation(probes):
    protocol = Protocol("1d", mesh=2, episodes=1)
    ready = prepare(linear, "hopper", protocol)
    assert isinstance(ready, PreparedPolicy) and probes == {"probe": 1, "adapt": 1}
    first = evaluate(ready, "hopper", protocol=protocol, workers=1)
    second = evaluate(ready, "hopper", protocol=protocol.replace(seed=3), workers=1)
    evaluate_dynamic(ready, lambda o: np.zeros((len(o), 3)), "hopper", game="nr", episodes=1)
    assert probes == {"probe": 1, "adapt": 1}  # nothing adapted or probed again
    plain = evaluate(linear, "hopper", protocol=protocol, workers=1)
    assert probes == {"probe": 2, "adapt": 2}  # a plain policy is prepared by evaluate itself
    pd.testing.assert_frame_equal(first.episodes, plain.episodes)
    assert first.config["policy_fingerprint"] == ready.fingerprint
    assert not first.episodes.equals(second.episodes)


def test_a_policy_prepared_for_other_observations_is_refused():
    ready = prepare(lambda o: np.zeros((len(o), 1)), "invertedpendulum", Protocol("1d"))
    with pytest.raises(ValueError, match="prepared for invertedpendulum .* prepare it again"):
        evaluate(ready, "hopper", "1d", mesh=2, episodes=1, workers=1)


def test_prepare_refuses_a_bad_policy_in_one_line():
    with pytest.raises(ValueError, match=r"expected \(2, 3\)"):
        prepare(lambda o: np.zeros((len(o), 2)), "hopper", Protocol("1d"))


def test_the_search_takes_a_protocol_with_the_same_rows_as_its_keywords():
    keywords = search_worst_case(linear, "hopper", "1d", budget=6, episodes=2, seed=3, workers=1)
    protocol = Protocol("1d", episodes=2, seed=3)
    given = search_worst_case(linear, "hopper", budget=6, workers=1, protocol=protocol)
    pd.testing.assert_frame_equal(keywords.trace, given.trace)
    paper = search_worst_case(
        linear, "hopper", budget=6, workers=1, protocol=protocol.replace(physics="paper")
    )
    assert not paper.trace["mean_return"].equals(given.trace["mean_return"])  # other physics


def test_the_search_refuses_a_protocol_with_keywords_and_a_schedule():
    with pytest.raises(ValueError, match="protocol= and episodes"):
        search_worst_case(linear, "hopper", episodes=3, protocol=Protocol("1d"))
    from rrls.wrappers import ScheduleFamily

    family = ScheduleFamily("drift", rate=[0.005, 0.02], direction=[-1, 1])
    with pytest.raises(ValueError, match="not schedule families"):
        search_worst_case(linear, "hopper", protocol=Protocol("1d", schedule=family))
