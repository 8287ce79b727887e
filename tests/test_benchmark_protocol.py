"""A benchmark holds its ``Protocol``: ``benchmark.json`` stores it as ``Protocol.to_json``
writes it, every earlier (flat) file reads into it with its fingerprints unchanged, and a
benchmark carrying disruptors, a schedule and an episode limit trains, evaluates and reports
under them."""

from __future__ import annotations

import importlib.util
import json
from dataclasses import replace
from pathlib import Path

import pandas as pd
import pytest

from rrls import files
from rrls.benchmark import benchfile, store
from rrls.benchmark.grid import PRESETS, Benchmark, SpecError, make_spec
from rrls.cli import main
from rrls.evaluation import Protocol, evaldir
from rrls.physics import physics_label
from rrls.report.reference import check_compatible, load_reference
from rrls.wrappers import ScheduleFamily

ROOT = Path(__file__).resolve().parents[1]
#: each shipped benchmark's fingerprints, computed from its flat benchmark.json before the
#: benchmark held its protocol whole (its runs' result.json record the same)
SHIPPED = {
    "halfcheetah": ("06fddb1da2e47f5c", "365e913d4cc24d42"),
    "halfcheetah/ablation": ("06fddb1da2e47f5c", "365e913d4cc24d42"),
    "hopper-200k": ("251d515ffab050de", "dbbed12e1380bcd5"),
    "hopper-200k/earlier": ("251d515ffab050de", "dbbed12e1380bcd5"),
    "hopper": ("06fddb1da2e47f5c", "899d7b58d338818b"),  # written whole (its protocol nested)
    "quick": ("af948eecfec71b33", "2c66c2bac2da6ff1"),
}
#: the presets' fingerprints, computed the same way before
PRESET_PRINTS = {
    "smoke": ("c3da4c495704f36d", "2a0780473e9eeafe"),
    "quick": ("af948eecfec71b33", "2c66c2bac2da6ff1"),
    "hopper-200k": ("251d515ffab050de", "dbbed12e1380bcd5"),
    "hopper": ("06fddb1da2e47f5c", "899d7b58d338818b"),
    "halfcheetah": ("06fddb1da2e47f5c", "365e913d4cc24d42"),
    "paper": ("06fddb1da2e47f5c", "dd8d49985117645e"),
}
FLAT_PROTOCOL = (
    "uncertainty", "mesh", "endpoint", "episodes", "dynamic_episodes", "eval_seed", "physics",
    "rate_limit", "rate_game", "split", "recheck",
)  # fmt: skip


def _shipped() -> list[Path]:
    found = sorted(p.parent for p in (ROOT / "docs/results").rglob("benchmark.json"))
    assert {str(p.relative_to(ROOT / "docs/results")) for p in found} == set(SHIPPED)
    return found


@pytest.mark.parametrize("name", sorted(SHIPPED))
def test_a_shipped_benchmark_keeps_its_fingerprints_and_its_runs(name):
    folder = ROOT / "docs/results" / name
    raw = json.loads((folder / benchfile.NAME).read_text())
    # the file as shipped: the flat format read in place, or (written since) the protocol whole
    assert ("protocol" in raw) == (name == "hopper")
    spec = benchfile.read_spec(folder)
    prints = spec.fingerprints()
    assert (prints["protocol"], prints["benchmark"]) == SHIPPED[name]
    for run in sorted((folder / "runs").glob("*")):  # every run still belongs to it
        result = store.read_result(run)
        assert {k: result[k] for k in prints if k in result} == {
            k: prints[k] for k in prints if k in result
        }, run


@pytest.mark.parametrize("preset", sorted(PRESET_PRINTS))
def test_the_presets_keep_their_fingerprints(preset):
    prints = make_spec(preset).fingerprints()
    assert (prints["protocol"], prints["benchmark"]) == PRESET_PRINTS[preset]


@pytest.mark.parametrize(
    "folder",
    [p for p in _shipped() if "protocol" not in json.loads((p / benchfile.NAME).read_text())],
    ids=lambda p: p.name,
)
def test_a_flat_benchmark_json_reads_into_a_protocol_and_back(folder, tmp_path):
    old = json.loads((folder / benchfile.NAME).read_text())
    spec = benchfile.read_spec(folder)
    assert spec.protocol == Protocol(
        old["uncertainty"],
        mesh=old["mesh"],
        episodes=old["episodes"],
        seed=old["eval_seed"],
        physics=old["physics"],
        endpoint=old.get("endpoint"),
        dynamic_episodes=old["dynamic_episodes"],
        rate_game=old["rate_game"],
    )
    assert spec.eval_seed == old["eval_seed"] and spec.mesh == old["mesh"]
    new = spec.to_json()  # what is written now: the protocol whole, nothing of it flat
    assert new["protocol"] == spec.protocol.to_json()
    assert not set(FLAT_PROTOCOL) & set(new)
    # its readers (the report, reference files) see the file as it was (today's physics label)
    was = {**old, "physics": physics_label(old["physics"])}
    assert {k: v for k, v in spec.flat_json().items() if k in old} == was
    benchfile.write_spec(tmp_path, spec)
    again = benchfile.read_spec(tmp_path)
    assert again == spec and again.fingerprints() == spec.fingerprints()
    assert benchfile.read_spec_json(tmp_path) == benchfile.read_spec_json(folder)


def test_every_earlier_format_reads_as_the_benchmark_it_was():
    flat = make_spec("smoke").flat_json()
    spec = Benchmark.from_json(flat)
    assert spec == make_spec("smoke")
    # before endpoint, simulator, recheck, rate_game and today's physics labels existed
    oldest = {k: v for k, v in flat.items() if k not in ("endpoint", "simulator", "rate_game")}
    assert Benchmark.from_json({**oldest, "physics": "rrls-v5"}) == spec
    before_tc = Benchmark.from_json({**oldest, "algos": ["rarl"], "rate_limit": 0.1})
    assert before_tc.protocol.rate_game == "target"  # rrls's earlier game, as it was played
    assert Benchmark.from_json({**flat, "split": ""}).protocol.split is None
    rechecked = Benchmark.from_json({**flat, "recheck": {"worst": 3, "episodes": 4}})
    assert (rechecked.recheck.worst, rechecked.recheck.episodes) == (3, 4)


def test_the_shipped_references_compare_with_the_migrated_benchmarks():
    for name in ("hopper-200k", "halfcheetah", "quick"):
        spec = benchfile.read_spec_json(ROOT / "docs/results" / name)
        check_compatible(load_reference(name), spec)  # the same protocol: no error
        other = {**spec, "mesh": spec["mesh"] + 1}
        with pytest.raises(ValueError, match="mesh"):
            check_compatible(load_reference(name), other)


def test_a_spec_holds_a_protocol_and_takes_its_fields_flat():
    proto = Protocol("1d", mesh=3, episodes=2, seed=7, max_episode_steps=40)
    spec = Benchmark(protocol=proto, algos=("td3",), tasks=("invertedpendulum",))
    assert spec.protocol is proto and spec.eval_seed == 7 and spec.uncertainty == "1d"
    assert Benchmark(protocol=proto, mesh=5).protocol == proto.replace(mesh=5)
    assert replace(spec, eval_seed=4).protocol == proto.replace(seed=4)
    assert Benchmark(protocol=proto.to_json()) == Benchmark(protocol=proto)
    assert Benchmark(**PRESETS["smoke"]).protocol.mesh == 2
    with pytest.raises(SpecError, match="mesh must be an integer"):
        Benchmark(mesh=0)
    with pytest.raises(TypeError, match="unknown field"):
        Benchmark(seed=3)  # the protocol's seed is eval_seed here, beside the training seeds
    with pytest.raises(AttributeError):
        spec.mesh = 4  # type: ignore[misc]


def test_what_a_protocol_adds_is_binding_and_named_when_it_differs(tmp_path):
    plain = make_spec("smoke", algos="td3")
    noisy = make_spec("smoke", algos="td3", disruptors={"obsnoise": 0.1})
    assert "disruptors" not in plain.binding_fields()  # a file written before: the same
    assert noisy.binding_fields()["disruptors"] == [["obsnoise", 0.1]]
    assert noisy.fingerprints()["benchmark"] != plain.fingerprints()["benchmark"]
    assert noisy.fingerprints()["protocol"] != plain.fingerprints()["protocol"]
    limited = make_spec("smoke", algos="td3", max_episode_steps=50)
    assert limited.binding_fields()["max_episode_steps"] == 50
    benchfile.write_spec(tmp_path, noisy)
    assert benchfile.reconcile(tmp_path, noisy) == noisy
    with pytest.raises(SpecError, match="disruptors: .*'obsnoise', 0.1.* there, None now"):
        benchfile.reconcile(tmp_path, plain)


def test_a_schedule_reads_back_from_benchmark_json(tmp_path):
    family = ScheduleFamily("drift", rate=[0.0, 0.01], direction=[-1, 1])
    spec = make_spec("smoke", algos="td3", schedule=family)
    benchfile.write_spec(tmp_path, spec)
    again = benchfile.read_spec(tmp_path)
    assert again.protocol.schedule == family and again.fingerprints() == spec.fingerprints()
    assert len(again.protocol.plan("invertedpendulum").points) == 4


@pytest.mark.parametrize(
    ("given", "needle"),
    [
        (dict(context=True), "context=true"),
        (dict(disruptors={"gravity": 0.1}), "unknown disruptor 'gravity'"),
        (dict(disruptors={"actiondelay": (0.0, 3.0)}, mesh=3), "actiondelay=1.5"),
        (dict(max_episode_steps=0), "max_episode_steps must be"),
        (dict(protocol={"mesh": 2, "bogus": 1}), "not protocol fields: bogus"),
    ],
)
def test_a_protocol_a_benchmark_cannot_run_is_refused_before_training(given, needle):
    with pytest.raises(SpecError, match=needle) as err:
        make_spec("smoke", algos="td3", **given)
    assert "\n" not in str(err.value)


def test_a_benchmark_json_with_a_hostile_protocol_is_one_line(tmp_path):
    data = make_spec("smoke").to_json()
    for bad, needle in (({"mesh": "3"}, "mesh must be an integer"), ([], "valid: an object")):
        files.write_checked_json(benchfile.spec_path(tmp_path), {**data, "protocol": bad})
        with pytest.raises(SpecError) as err:
            benchfile.read_spec(tmp_path)
        assert "benchmark.json" in str(err.value) and needle in str(err.value)
        assert "\n" not in str(err.value)
    files.write_checked_json(benchfile.spec_path(tmp_path), {**data, "mesh": 3})
    with pytest.raises(SpecError, match="unknown field 'mesh'"):  # not both formats at once
        benchfile.read_spec(tmp_path)


def test_a_protocol_file_that_is_not_one_is_one_line(tmp_path, capsys):
    (tmp_path / "p.json").write_text('{"mesh": 2, "disruptors": 5}')
    argv = ["benchmark", "--preset", "smoke", "--algos", "td3", "--dry-run"]
    assert main([*argv, "--out", str(tmp_path / "b"), "--protocol", str(tmp_path / "p.json")]) == 2
    err = capsys.readouterr().err.strip()
    assert "p.json" in err and "disruptors must be" in err and len(err.splitlines()) == 1
    assert main([*argv, "--out", str(tmp_path / "b"), "--protocol", str(tmp_path / "no")]) == 2
    assert "no" in capsys.readouterr().err
    assert not (tmp_path / "b").exists()


@pytest.mark.e2e  # a training run: the end-to-end tier (.ci/run)
@pytest.mark.skipif(importlib.util.find_spec("torch") is None, reason="training needs torch")
def test_a_benchmark_trains_evaluates_and_reports_under_its_protocol(tmp_path, capsys):
    """Disruptors, a schedule and an episode limit from ``--protocol FILE``: HalfCheetah never
    terminates, so every episode of the training and of the evaluation ends at the limit."""
    wanted = Protocol(
        "1d",
        mesh=2,
        episodes=1,
        dynamic_episodes=1,
        disruptors={"obsnoise": 0.05},
        schedule=ScheduleFamily("drift", rate=[0.0, 0.01]),
        max_episode_steps=20,
    )
    (tmp_path / "protocol.json").write_text(json.dumps(wanted.to_json()))
    out = tmp_path / "bench"
    argv = ["benchmark", "--preset", "smoke", "--algos", "td3", "--tasks", "halfcheetah"]
    argv += ["--workers", "1", "--out", str(out)]
    assert main([*argv, "--protocol", str(tmp_path / "protocol.json")]) == 0
    assert json.loads((out / "benchmark.json").read_text())["protocol"] == wanted.to_json()
    run = out / "runs" / "td3-halfcheetah-1d-seed0"
    scalars = pd.read_csv(run / "scalars.csv")
    lengths = scalars.loc[scalars["metric"] == "charts/episode_length", "value"]
    assert len(lengths) >= 10 and set(lengths) == {20.0}  # training truncated at the limit
    config = json.loads((run / "eval" / "evaluation.json").read_text())
    assert config["disruptors"] == {"obsnoise": 0.05} and config["max_episode_steps"] == 20
    assert config["schedule"] == wanted.schedule.to_json()
    episodes = evaldir.read(run / "eval")[1]
    assert sorted(episodes["drift_rate"]) == [0.0, 0.01] and set(episodes["length"]) == {20}
    assert store.read_result(run)["protocol"] == wanted.fingerprint()
    summary = json.loads((out / "report" / "summary.json").read_text())["benchmark"]
    assert summary["max_episode_steps"] == 20 and summary["disruptors"] == [["obsnoise", 0.05]]
    report = (out / "report" / "report.md").read_text()
    line = next(x for x in report.splitlines() if x.startswith("- evaluated under"))
    assert "`obsnoise` 0.05" in line and "`drift` schedule" in line and "20 steps" in line
    # another protocol over the same directory is refused, naming what differs
    capsys.readouterr()
    assert main([*argv, "--protocol", str(tmp_path / "protocol.json"), "--mesh", "3"]) == 2
    assert "mesh: 2 there, 3 now" in capsys.readouterr().err


@pytest.mark.parametrize(
    ("schedule", "needle"),
    [
        (5, "schedule must be null or"),
        ({"kind": "drift"}, "schedule must be null or"),
        ({"kind": "drift", "grid": {"rate": 0.1}}, "schedule must be null or"),
        ({"kind": "bogus", "grid": {"rate": [0.1]}}, "unknown schedule 'bogus'"),
        ({"kind": "drift", "grid": {"speed": [0.1]}}, "drift has no field"),
        ({"kind": "drift", "grid": {"rate": ["x"]}}, "could not convert"),
    ],
)
def test_a_hostile_schedule_is_refused_by_the_protocol(schedule, needle):
    with pytest.raises(ValueError, match=needle):
        Protocol.from_json({"uncertainty": "1d", "schedule": schedule})
