"""A run's hyper-parameters given typed: ``TrainConfig(hyper=td3.Config(...))`` is the same run
as the same overrides given as a dict, and a ``Config`` of another algorithm is one line."""

from __future__ import annotations

from dataclasses import asdict

import pytest

from rrls.agents import TrainConfig, resolve_run


def test_a_typed_config_resolves_as_the_same_overrides_in_a_dict():
    from rrls.agents.algos import td3

    typed = resolve_run(TrainConfig(algo="td3", hyper=td3.Config(tau=0.01, batch_size=64)))
    plain = resolve_run(TrainConfig(algo="td3", hyper={"tau": 0.01, "batch_size": 64}))
    assert typed.hyper == plain.hyper and typed.hyper.tau == 0.01
    same = TrainConfig(algo="td3")
    assert same.identity(typed.hyper) == same.identity(plain.hyper)
    assert asdict(typed.hyper)["batch_size"] == 64


def test_another_algorithms_config_is_refused_in_one_line():
    from rrls.agents.algos import sac

    with pytest.raises(ValueError, match=r"^hyper is a .*sac.Config; td3 takes its .*td3.Config"):
        resolve_run(TrainConfig(algo="td3", hyper=sac.Config()))
