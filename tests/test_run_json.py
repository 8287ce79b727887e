"""``run.json`` describes a run once (its settings, the algorithm's resolved ``Config`` inside),
and every shipped run, written before, reads into that form with nothing lost or changed."""

from __future__ import annotations

import json
from dataclasses import asdict
from pathlib import Path

import pytest

from rrls.algorithms import built_in
from rrls.rundir import migrate_run_json, read_run_json

pytest.importorskip("torch")
from rrls.agents import TrainConfig, hyperparameters
from rrls.agents.hparams import jsonable

#: hyper-parameters added after shipped runs were trained, each defaulting to the behaviour
#: before it (their modules' docstrings): M2TD3's and NR-MDP's authors' details, opt-in;
#: RARL's schedule, ``simultaneous`` as the shipped runs trained
ADDED_SINCE = {
    "m2td3": {"clip_exploration", "same_start"},
    "nrmdp": {"normalize_obs", "critic_weight_decay"},
    "rarl": {"schedule"},
}
ADDED_SINCE.update({a: set() for a in ("td3", "dr", "sac", "sacdr")})
SHIPPED = sorted((Path(__file__).parents[1] / "docs" / "results").rglob("run.json"))


def test_every_reference_ships_runs():
    assert len(SHIPPED) >= 50  # HalfCheetah's 25, Hopper's 15, the quick reference's


@pytest.mark.parametrize("path", SHIPPED, ids=lambda p: p.parent.name)
def test_a_shipped_run_json_reads_as_the_run_described_once(path):
    raw = json.loads(path.read_text())
    run = read_run_json(path.parent)
    assert "hyperparameters" not in run
    hyper = run["config"]["hyper"]
    if "hyperparameters" in raw:  # written before: the resolved ones beside the overrides
        assert hyper == raw["hyperparameters"]  # nothing lost
        # the overrides the old file kept are in it, with their values
        assert all(hyper[k] == v for k, v in raw["config"]["hyper"].items())
    else:  # written in today's form (the longer Hopper grid's runs): read as it is
        assert run == raw
    # and today's Config with those overrides is the same run: no default drifted since (a
    # plug-in's run, e.g. the M2TD3 authors' code as a learner, needs its plug-in installed)
    if raw["config"]["algo"] not in built_in():
        return
    settings = {k: v for k, v in raw["config"].items() if k in TrainConfig.__dataclass_fields__}
    config = TrainConfig(**{**settings, "hyper": raw["config"]["hyper"], "out": None})
    today = jsonable(asdict(hyperparameters(config)))
    assert {k: today[k] for k in hyper} == hyper
    # hyper-parameters added since, opt-in: their defaults are the behaviour before them
    assert set(today) - set(hyper) <= ADDED_SINCE[raw["config"]["algo"]]
    # the rest of the file is untouched
    assert {k: v for k, v in run.items() if k != "config"} == {
        k: v for k, v in raw.items() if k not in ("config", "hyperparameters")
    }


def test_a_run_json_in_todays_form_reads_unchanged():
    today = {"algorithm": "td3", "steps": 10, "config": {"hyper": {"learning_rate": 1e-3}}}
    assert migrate_run_json(today) is today
