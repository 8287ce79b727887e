"""A benchmark builds each run's settings from one template: its shared settings under their own
names, the run's algorithm, task, seed and directory, and what it derives per run."""

from __future__ import annotations

from dataclasses import fields

import pytest

from rrls.agents.config import TrainConfig
from rrls.benchmark.grid import SHARED_SETTINGS, Benchmark, RunKey, make_spec

pytest.importorskip("torch")  # a TrainConfig checks its algorithm and device when made

#: the settings both name that ``run_settings`` derives per run instead of copying
DERIVED = {"uncertainty", "simulator"}


def test_every_setting_a_benchmark_shares_by_name_reaches_its_runs():
    names = {f.name for f in fields(TrainConfig)}
    benchmark = {name for name in dir(Benchmark) if not name.startswith("_")}
    assert set(SHARED_SETTINGS) == (names & benchmark) - DERIVED


@pytest.mark.parametrize("preset", ["smoke", "quick", "halfcheetah"])
def test_a_runs_settings_are_the_benchmarks_with_the_run_put_in(preset, tmp_path):
    spec = make_spec(preset, steps=1000, eval_every=500)
    for algo in spec.algos:
        run = RunKey(algo, spec.tasks[0], 3)
        config = spec.run_settings(run, tmp_path / algo)
        assert (config.algo, config.task, config.seed) == (algo, spec.tasks[0], 3)
        assert config.out == str(tmp_path / algo) and config.threads == 1
        assert config.uncertainty == spec.train_set(algo)
        assert config.hyper == spec.hyperparameters(algo)
        assert all(getattr(config, name) == getattr(spec, name) for name in SHARED_SETTINGS)
        assert config.max_episode_steps is not None  # the task's, where the protocol has none
