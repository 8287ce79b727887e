"""Options declared once: ``rrls benchmark``'s run settings are ``TrainConfig``'s fields, and the
protocol's options of ``rrls evaluate`` and ``rrls benchmark`` are ``Protocol``'s, with their
help, their choices and (``evaluate``) their defaults read from the field."""

from __future__ import annotations

import argparse
from dataclasses import fields

import pytest

from rrls.agents.config import TrainConfig
from rrls.cli import benchmark_command, evaluate_command
from rrls.evaluation.protocol import Protocol

SETTINGS = ("uncertainty", "split", "physics", "simulator", "steps", "eval_every", "device")


def _parser(module) -> argparse.ArgumentParser:
    return module.add_parser(argparse.ArgumentParser().add_subparsers())


def _actions(parser: argparse.ArgumentParser) -> dict[str, argparse.Action]:
    return {a.dest: a for a in parser._actions}


@pytest.mark.parametrize("name", SETTINGS)
def test_a_benchmark_setting_is_its_train_config_field(name):
    field = {f.name: f for f in fields(TrainConfig)}[name]
    action = _actions(_parser(benchmark_command))[name]
    assert action.help.startswith(field.metadata["help"])
    assert action.help.endswith("(default: the preset's)") and action.default is None
    assert action.choices == field.metadata.get("choices")


@pytest.mark.parametrize("name", ["mesh", "episodes"])
def test_the_protocols_options_are_its_fields(name):
    field = {f.name: f for f in fields(Protocol)}[name]
    evaluate = _actions(_parser(evaluate_command))[name]
    assert evaluate.default == getattr(Protocol(), name)  # no second copy of the default
    assert (
        field.metadata["help"] in evaluate.help and f"(default: {field.default})" in evaluate.help
    )
    benchmark = _actions(_parser(benchmark_command))[name]
    assert benchmark.default is None and field.metadata["help"] in benchmark.help


def test_a_benchmark_parses_a_step_count_in_any_spelling():
    args = _parser(benchmark_command).parse_args(["--out", "x", "--steps", "100k"])
    assert args.steps == 100_000 and args.uncertainty is None


def test_the_warm_up_options_help_reads_the_table_and_the_quick_preset():
    from rrls.algorithms import ALGORITHMS
    from rrls.benchmark.presets import PRESETS

    text = _actions(_parser(benchmark_command))["learning_starts"].help
    assert f"M2TD3 {ALGORITHMS['m2td3'].learning_starts:,}" in text
    assert f"own, {ALGORITHMS['td3'].learning_starts:,}" in text
    assert f"quick {PRESETS['quick']['learning_starts']:,}" in text


@pytest.mark.parametrize("name", ["rate_limit", "recheck"])
def test_the_adversary_and_recheck_options_are_the_protocols_fields(name):
    field = {f.name: f for f in fields(Protocol)}[name]
    action = _actions(_parser(benchmark_command))[name]
    assert action.help.startswith(field.metadata["help"]) and action.default is None
    assert action.metavar == field.metadata["metavar"]
    assert f"the paper's: {field.metadata['none']})" in action.help  # Protocol's None, said


def test_the_parsed_adversary_and_recheck_are_what_the_protocol_holds():
    from rrls.cli.benchmark_options import spec_from

    args = _parser(benchmark_command).parse_args(
        ["--out", "x", "--preset", "smoke", "--rate-limit", "0.001", "--recheck", "3x4"]
    )
    args.workers = 1
    spec, _ = spec_from(args)
    assert spec.protocol.rate_limit == 0.001
    assert (spec.protocol.recheck.worst, spec.protocol.recheck.episodes) == (3, 4)


def test_observe_is_the_benchmarks_field_with_its_choices():
    from rrls.benchmark.grid import Benchmark

    field = {f.name: f for f in fields(Benchmark)}["observe"]
    action = _actions(_parser(benchmark_command))["observe"]
    assert action.help.startswith(field.metadata["help"]) and action.default is None
    assert tuple(action.choices) == field.metadata["choices"] == ("vanilla", "stacked", "oracle")
