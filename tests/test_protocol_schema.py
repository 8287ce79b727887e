"""``Protocol`` accepts only what it claims: every field's type and range is checked however the
protocol is made (``Protocol(...)`` or ``from_json``), with one line naming the field and value,
and every protocol reads back from its JSON as itself."""

from __future__ import annotations

import json
import math

import pytest

from rrls.evaluation.protocol import Protocol
from rrls.schema import SchemaError
from rrls.uncertainty import Split, UncertaintySet

HOSTILE = [
    ([], "a protocol is a JSON object"),
    ("", "a protocol is a JSON object"),
    (None, "a protocol is a JSON object"),
    ({"endpoint": "no"}, "endpoint must be true, false or null"),
    ({"endpoint": 1}, "endpoint must be"),
    ({"context": "false"}, "context must be true or false"),
    ({"rate_limit": math.nan}, "rate_limit must be"),
    ({"rate_limit": math.inf}, "rate_limit must be"),
    ({"rate_limit": -1}, "rate_limit must be"),
    ({"rate_limit": "x"}, "rate_limit must be"),
    ({"rate_limit": True}, "rate_limit must be"),
    ({"rate_game": "bogus"}, "rate_game must be one of"),
    ({"mesh": 2.9}, "mesh must be an integer"),
    ({"mesh": "3"}, "mesh must be an integer"),
    ({"episodes": 0}, "episodes must be an integer"),
    ({"dynamic_episodes": -2}, "dynamic_episodes must be"),
    ({"max_episode_steps": 0}, "max_episode_steps must be"),
    ({"seed": -1}, "seed must be an integer"),
    ({"seed": 2**32}, "seed must be an integer"),
    ({"seed": 1e400}, "seed must be an integer"),
    ({"physics": "v9"}, "unknown physics"),
    ({"physics": 5}, "physics must be"),
    ({"uncertainty": 3}, "uncertainty must be"),
    ({"uncertainty": {"names": ["torsomass"], "high": [2.0]}}, "missing low"),
    ({"uncertainty": {"names": ["torsomass"], "low": [math.nan], "high": [2.0]}}, "finite"),
    ({"split": 3}, "split must be"),
    ({"split": {"kind": "extrapolation"}}, "missing"),
    ({"disruptors": 5}, "disruptors must be name: strength pairs"),
    ({"disruptors": [["obs_noise", "x"]]}, "strength must be a finite number"),
    ({"disruptors": [["obs_noise", math.nan]]}, "strength must be a finite number"),
    ({"not_a_field": 1}, "not protocol fields"),
]


@pytest.mark.parametrize(("data", "message"), HOSTILE)
def test_a_hostile_protocol_is_refused_naming_the_field(data, message):
    with pytest.raises(ValueError, match=message):
        Protocol.from_json(data)


def test_the_constructor_checks_as_from_json_does():
    with pytest.raises(ValueError, match="context must be true or false"):
        Protocol(context="false")
    with pytest.raises(ValueError, match="rate_limit must be"):
        Protocol(rate_limit=math.nan)


BOX = UncertaintySet.from_bounds({"torsomass": (1.0, 5.0), "worldfriction": (0.5, 2.0)})


@pytest.mark.parametrize(
    "protocol",
    [
        Protocol(),
        Protocol(uncertainty="2d", mesh=3, episodes=2, seed=7, endpoint=False, physics="paper"),
        Protocol(uncertainty=BOX, split=Split.extrapolation(BOX, inner=0.5)),
        Protocol(split="extrapolation:0.4"),
        Protocol(disruptors={"obs_noise": (0.0, 0.1)}, context=True, max_episode_steps=50),
        Protocol(rate_limit=0.1, rate_game="target", dynamic_episodes=3),
    ],
)
def test_every_protocol_reads_back_as_itself(protocol):
    again = Protocol.from_json(json.loads(json.dumps(protocol.to_json())))
    assert again == protocol
    assert again.to_json() == protocol.to_json()


def test_sizes_are_bounded_before_anything_is_allocated():
    import time

    from rrls.uncertainty import MAX_MESH_POINTS

    start = time.perf_counter()
    with pytest.raises(ValueError, match=r"100,000,000 points; at most 1,000,000"):
        Protocol(uncertainty="1d", mesh=100_000_000).plan("hopper")
    with pytest.raises(ValueError, match=r"at most 1,000,000 \(a mesh of 100 here\)"):
        Protocol(uncertainty="3d", mesh=101).plan("hopper")
    with pytest.raises(ValueError, match=r"episodes; at most 100,000,000 per evaluation"):
        Protocol(uncertainty="1d", mesh=1000, episodes=1_000_000).plan("hopper")
    assert time.perf_counter() - start < 5  # refused, not computed
    assert len(Protocol(uncertainty="3d", mesh=100, episodes=1).plan("hopper").points) == (
        MAX_MESH_POINTS
    )


def test_the_cli_refuses_a_huge_mesh_in_one_line(tmp_path, capsys):
    from rrls.cli import main
    from rrls.evaluation.policies import MLPPolicy

    policy = str(MLPPolicy.random(11, 3, hidden=(8,)).save(tmp_path / "p.npz"))
    argv = ["evaluate", policy, "--task", "hopper", "--uncertainty", "1d", "--mesh", "100000000"]
    assert main([*argv, "--out", str(tmp_path / "e")]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and "at most 1,000,000" in lines[0], lines


@pytest.mark.parametrize(
    "keyword",
    [{"mesh": 3}, {"episodes": 2}, {"seed": 1}, {"endpoint": False}, {"paper": True},
     {"context": True}, {"max_episode_steps": 50}, {"disruptors": {"obsnoise": 0.1}},
     {"uncertainty": "1d"}],
)  # fmt: skip
def test_evaluate_refuses_a_protocol_and_its_fields_together(keyword):
    from rrls.evaluation import MLPPolicy, evaluate

    policy = MLPPolicy.random(4, 1, (8,), seed=0)
    with pytest.raises(ValueError, match=f"protocol= and {next(iter(keyword))}"):
        evaluate(policy, "invertedpendulum", protocol=Protocol("1d", mesh=2, episodes=1), **keyword)


def test_a_policys_default_protocol_comes_from_one_constructor():
    """``Protocol.for_policy``: the set and physics it trained on, its split on its own set; any
    given field overrides; a set the task lacks falls back to the task's benchmark set."""
    meta = {"uncertainty": "2d", "physics": "paper", "split": "extrapolation:0.5"}
    own = Protocol.for_policy(meta, "hopper")
    assert (own.uncertainty, own.physics, own.split) == ("2d", "paper", "extrapolation:0.5")
    other = Protocol.for_policy(meta, "hopper", uncertainty="3d", mesh=3, physics="v5")
    assert (other.uncertainty, other.split, other.mesh, other.physics) == ("3d", None, 3, "v5")
    assert Protocol.for_policy({}, "invertedpendulum").uncertainty == "2d"
    assert Protocol.for_policy({"uncertainty": "9d"}, "hopper").uncertainty == "3d"
    with pytest.raises(ValueError, match="not protocol fields: workers"):
        Protocol.for_policy({}, "hopper", workers=2)


# --- a protocol's own box and split, typed ---------------------------------------------------
_BOX = Protocol(uncertainty=BOX, split=Split.extrapolation(BOX, inner=0.5)).to_json()


@pytest.mark.parametrize(
    ("part", "field", "bad", "named"),
    [
        ("uncertainty", "names", "pm", "'uncertainty.names' is 'pm'"),  # was two names p, m
        ("uncertainty", "names", ["torsomass", 3], "'uncertainty.names[1]' is 3"),
        ("uncertainty", "names", [True, "m"], "'uncertainty.names[0]' is True"),
        ("uncertainty", "low", ["1", 0.5], "'uncertainty.low[0]' is '1'"),  # was 1.0
        ("uncertainty", "high", [True, 2.0], "'uncertainty.high[0]' is True"),  # was 1.0
        ("uncertainty", "high", [None, 2.0], "'uncertainty.high[0]' is None"),
        ("uncertainty", "low", "1.0", "'uncertainty.low' is '1.0'"),
        ("uncertainty", "low", [1.0], "'uncertainty.low' holds 1 values"),
        ("uncertainty", "high", [5.0, 2.0, 3.0], "'uncertainty.high' holds 3 values"),
        ("uncertainty", "nominal", ["1", 1.0], "'uncertainty.nominal[0]' is '1'"),
        ("uncertainty", "nominal", [1.0], "'uncertainty.nominal' holds 1 values"),
        ("uncertainty", "label", 3, "'uncertainty.label' is 3"),
        ("uncertainty", "family", "bogus", "'uncertainty.family' is 'bogus'"),
        ("uncertainty", "extra", 1, "unknown field 'uncertainty.extra'"),
        ("split", "names", "pm", "'split.names' is 'pm'"),
        ("split", "kind", 3, "'split.kind' is 3"),
        ("split", "region_low", [True, 1.0], "'split.region_low[0]' is True"),
        ("split", "region_high", ["2", 1.5], "'split.region_high[0]' is '2'"),
        ("split", "high", [5.0], "'split.high' holds 1 values"),
    ],
)
def test_a_protocols_box_and_split_are_typed(part, field, bad, named):
    data = json.loads(json.dumps(_BOX))
    data[part][field] = bad
    with pytest.raises(SchemaError) as err:
        Protocol.from_json(data)
    text = str(err.value)
    assert "\n" not in text and text.startswith("protocol: ") and named in text, text
    assert "valid" in text


def test_a_split_read_alone_is_typed_too():
    data = {**_BOX["split"], "names": "pm"}
    with pytest.raises(SchemaError, match="split: field 'names' is 'pm'; valid: a list of"):
        Split.from_json(data)
    assert Split.from_json(_BOX["split"]) == Split.extrapolation(BOX, inner=0.5)
