"""Every file rrls reads is checked against its one schema: for each field of each format, the
hostile values a field of its kind can meet (wrong types, NaN, infinities, out-of-range
numbers, unknown choices, unknown keys) are refused in one line naming the file, the field and
what is valid; what rrls writes reads back."""

from __future__ import annotations

import json
import math
from dataclasses import fields
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pytest

from rrls import files, rundir
from rrls.benchmark import benchfile, store
from rrls.benchmark.grid import PRESETS, Benchmark, SpecError
from rrls.evaluation import EvaluationResult, evaldir
from rrls.evaluation.policies import HEADER_SCHEMA
from rrls.report.reference import (
    REFERENCE_SCHEMA,
    ReferenceError,
    load_reference,
)
from rrls.schema import Field, Schema, SchemaError, TableSchema, integer, number, string

ROOT = Path(__file__).resolve().parents[1]


def hostile(spec: Field) -> list[Any]:
    """Values a field of this kind must refuse."""
    out: list[Any] = [{"an": "object"}] if spec.kind != "object" else ["text", 3, [1]]
    if spec.kind in ("int", "number"):
        out += ["7", True, math.nan, math.inf, -math.inf]
        if spec.kind == "int":
            out += [2.5, 1e400 if False else 2.0**70]
        if spec.low is not None:
            out.append(spec.low - 1 if spec.kind == "int" else spec.low - 1.5)
        if spec.high is not None:
            out.append(spec.high + 1)
    elif spec.kind == "bool":
        out += ["false", "no", 0, 1]
    elif spec.kind == "str":
        out += [5, True, ["a"]]
    elif spec.kind == "list":
        out += ["text", 3]
        if spec.items is not None:
            out += [[bad] for bad in hostile(spec.items)[:3]]
    if spec.choices is not None:
        out.append("bogus")
    if not spec.null:
        out.append(None)
    return [v for v in out if not (spec.kind == "object" and isinstance(v, dict))]


def cases(schema: Schema) -> list[tuple[str, Any]]:
    return [
        (name, bad)
        for name, spec in schema.fields.items()
        if spec.kind not in ("any",)
        for bad in hostile(spec)
    ]


def one_line(err: BaseException, *words: str) -> None:
    text = str(err)
    assert "\n" not in text and "Traceback" not in text
    for word in words:
        assert word in text, (word, text)


# --- the validator itself -------------------------------------------------------------------
def test_the_validator_names_file_field_value_and_what_is_valid():
    schema = Schema({"mesh": integer(1, 10), "rows": Field("list", items=number())})
    with pytest.raises(SchemaError) as err:
        schema.check({"mesh": 11}, "F.json")
    one_line(err.value, "F.json", "'mesh'", "11", "in [1, 10]")
    with pytest.raises(SchemaError) as err:
        schema.check({"rows": [1.0, math.nan]}, "F.json")
    one_line(err.value, "'rows[1]'", "nan", "finite")
    with pytest.raises(SchemaError) as err:
        schema.check({"mesh": 2, "mesh2": 3}, "F.json")
    one_line(err.value, "unknown field 'mesh2'", "valid fields: mesh, rows")
    with pytest.raises(SchemaError, match="is missing"):
        Schema({"a": string(required=True)}).check({}, "F.json")
    for bad in ([], "", 3, None):
        with pytest.raises(SchemaError, match="an object of fields"):
            schema.check(bad, "F.json")
    # numpy scalars (a CSV's cells) are the values they hold
    assert schema.check({"mesh": np.int64(3)}, "F") == {"mesh": np.int64(3)}


def test_table_headers_are_checked():
    table = TableSchema({"point": "int", "return": "number", "terminated": "bool"})
    good = pd.DataFrame({"point": [0], "return": [1.5], "terminated": [False], "extra": ["x"]})
    assert table.check(good, "T") is good
    for column, value in (("point", 1.5), ("return", "x"), ("return", np.inf), ("terminated", 1)):
        bad = good.assign(**{column: [value]})
        with pytest.raises(SchemaError) as err:
            table.check(bad, "T.csv")
        one_line(err.value, "T.csv", repr(column))
    with pytest.raises(SchemaError, match="'point' is missing"):
        table.check(good.drop(columns="point"), "T.csv")


# --- benchmark.json -------------------------------------------------------------------------
def test_the_spec_schema_declares_every_spec_field():
    assert set(benchfile.SPEC_SCHEMA.fields) == {f.name for f in fields(Benchmark)}
    for name, preset in PRESETS.items():  # every preset writes a file that reads back
        spec = Benchmark(**{**preset, "preset": name})
        benchfile.SPEC_SCHEMA.check(spec.to_json(), name)


@pytest.mark.parametrize(("field", "bad"), cases(benchfile.SPEC_SCHEMA))
def test_a_hostile_benchmark_json_is_refused_by_field(tmp_path, field, bad):
    data = Benchmark(**PRESETS["smoke"]).to_json()
    data[field] = bad
    files.write_checked_json(benchfile.spec_path(tmp_path), data)
    with pytest.raises(SpecError) as err:
        benchfile.read_spec(tmp_path)
    one_line(err.value, "benchmark.json", f"'{field}")


def test_the_flat_schema_declares_every_field_an_earlier_file_held():
    from rrls.benchmark.grid import LATER, PROTOCOL_NAMES

    earlier = set(PROTOCOL_NAMES) - set(LATER)  # the protocol's fields files held flat
    assert (
        set(benchfile.FLAT_SCHEMA.fields)
        == set(benchfile.SPEC_SCHEMA.fields) - {"protocol"} | earlier
    )
    for name, preset in PRESETS.items():  # every preset, written as then, reads back
        spec = Benchmark(**{**preset, "preset": name})
        assert Benchmark.from_json(benchfile.FLAT_SCHEMA.check(spec.flat_json(), name)) == spec


@pytest.mark.parametrize(("field", "bad"), cases(benchfile.FLAT_SCHEMA))
def test_a_hostile_flat_benchmark_json_is_refused_by_field(tmp_path, field, bad):
    data = Benchmark(
        **PRESETS["smoke"]
    ).flat_json()  # as benchmark.json held it before the protocol
    data[field] = bad
    files.write_checked_json(benchfile.spec_path(tmp_path), data)
    with pytest.raises(SpecError) as err:
        benchfile.read_spec(tmp_path)
    one_line(err.value, "benchmark.json", f"'{field}")


def test_a_benchmark_json_with_an_unknown_field_is_refused(tmp_path):
    data = {**Benchmark(**PRESETS["smoke"]).to_json(), "physic": "v5"}
    files.write_checked_json(benchfile.spec_path(tmp_path), data)
    with pytest.raises(SpecError, match="unknown field 'physic'"):
        benchfile.read_spec(tmp_path)


# --- result.json ----------------------------------------------------------------------------
RESULT = {
    "algorithm": "td3",
    "task": "hopper",
    "uncertainty": "3d",
    "seed": 0,
    "steps": 100,
    "worst_case": 1.0,
    "average_case": 2.0,
}


@pytest.mark.parametrize(("field", "bad"), cases(store.RESULT_SCHEMA))
def test_a_hostile_result_json_is_refused_by_field(tmp_path, field, bad):
    files.write_checked_json(tmp_path / rundir.RESULT, {**RESULT, field: bad})
    with pytest.raises(SchemaError) as err:
        store.read_result(tmp_path)
    one_line(err.value, "result.json", f"'{field}")
    with pytest.raises(SchemaError):  # and nothing writes one
        store.write_result(tmp_path / "other", {**RESULT, field: bad})


def test_every_shipped_result_and_run_file_matches_its_schema():
    runs = sorted((ROOT / "docs/results").glob("*/runs/*"))
    assert len(runs) >= 18  # the hopper and halfcheetah pages
    for run in runs:
        if (run / rundir.RESULT).exists():
            store.read_result(run)
        if (run / rundir.RUN_JSON).exists():
            rundir.read_run_json(run)


# --- run.json -------------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("field", "bad"), [c for c in cases(rundir.RUN_SCHEMA) if c[0] in ("steps", "algorithm")]
)
def test_a_hostile_run_json_is_a_damaged_run(tmp_path, field, bad):
    good = json.loads(
        (ROOT / "docs/results/hopper-200k/runs/td3-hopper-3d-seed0/run.json").read_text()
    )
    files.write_checked_json(tmp_path / rundir.RUN_JSON, {**good, field: bad})
    (tmp_path / rundir.POLICY).write_bytes(b"")
    with pytest.raises(files.DamagedFile) as err:
        rundir.read_run_json(tmp_path)
    one_line(err.value, "run.json", f"'{field}")
    assert rundir.finished_steps(tmp_path) is None  # not a finished run: it trains again


# --- reference files ------------------------------------------------------------------------
def _reference() -> dict[str, Any]:
    return json.loads((ROOT / "rrls/report/hopper_200k_reference.json").read_text())


@pytest.mark.parametrize(("field", "bad"), cases(REFERENCE_SCHEMA))
def test_a_hostile_reference_is_refused_by_field(tmp_path, field, bad):
    path = tmp_path / "ref.json"
    path.write_text(json.dumps({**_reference(), field: bad}))
    with pytest.raises(ReferenceError) as err:
        load_reference(path)
    one_line(err.value, str(path), f"'{field}")


@pytest.mark.parametrize(
    ("field", "bad"),
    [("mean", math.nan), ("mean", "x"), ("std", -1.0), ("n_seeds", 1e400), ("n_seeds", 0)]
    + [("metric", "best_case"), ("values", [1.0, math.inf]), ("task", None), ("values", "1;2")],
)
def test_a_hostile_reference_row_is_refused(tmp_path, field, bad):
    data = _reference()
    data["rows"][3][field] = bad
    path = tmp_path / "ref.json"
    path.write_text(json.dumps(data))
    with pytest.raises(ReferenceError) as err:
        load_reference(path)
    one_line(err.value, f"rows[3].{field}")


def test_a_reference_row_whose_seeds_and_values_disagree_is_refused(tmp_path):
    data = _reference()
    row = next(r for r in data["rows"] if r.get("values"))
    row["n_seeds"] = len(row["values"]) + 1
    path = tmp_path / "ref.json"
    path.write_text(json.dumps(data))
    with pytest.raises(ReferenceError, match="n_seeds"):
        load_reference(path)


def test_a_csv_reference_reads_as_its_json_and_is_checked_the_same(tmp_path):
    ref = load_reference("hopper-200k")
    csv = ref.save(tmp_path / "ref.csv")
    back = load_reference(csv)
    assert back.rows == ref.rows and back.mesh == ref.mesh and back.endpoint == ref.endpoint
    frame = pd.read_csv(csv)
    for column, value in (("mesh", 2.9), ("mean", "x"), ("metric", "best"), ("physics", "v9")):
        frame.assign(**{column: value}).to_csv(tmp_path / "bad.csv", index=False)
        with pytest.raises(ReferenceError) as err:
            load_reference(tmp_path / "bad.csv")
        one_line(err.value, "bad.csv", column)


# --- runs bound to their benchmark's protocol ----------------------------------------------
def test_a_protocol_fingerprint_names_its_fields():
    spec = Benchmark(**PRESETS["smoke"])
    a = spec.fingerprints()
    assert a == Benchmark.from_json(json.loads(json.dumps(spec.to_json()))).fingerprints()
    assert set(a) == {"protocol", "benchmark"} and all(len(v) == 16 for v in a.values())
    # the grid and the labels may change within one benchmark; the protocol may not
    from dataclasses import replace

    assert replace(spec, seeds=(0, 1, 2), device="cuda").fingerprints() == a
    assert replace(spec, mesh=3).fingerprints()["protocol"] != a["protocol"]
    assert replace(spec, steps=400).fingerprints()["benchmark"] != a["benchmark"]
    assert replace(spec, steps=400).fingerprints()["protocol"] == a["protocol"]


def _benchmark_with_one_run(root: Path, result: dict[str, Any]) -> Path:
    spec = Benchmark(
        **{**PRESETS["smoke"], "algos": ("td3",), "tasks": ("hopper",), "uncertainty": "3d"}
    )
    benchfile.write_spec(root, spec)
    run = root / "runs" / "td3-hopper-3d-seed0"
    (run / "eval").mkdir(parents=True)
    episodes = pd.DataFrame(
        {
            "point": [0, 1],
            "episode": [0, 0],
            "seed": [1, 2],
            "return": [1.0, 3.0],
            "length": [10, 10],
            "terminated": [False, False],
            "diverged": [False, False],
        }
    )
    files.write_checked_table(run / "eval" / "episodes.csv", episodes)
    store.write_result(run, {**RESULT, "steps": spec.steps, **result})
    return run


def test_a_result_from_another_protocol_is_refused_by_the_store_and_the_report(tmp_path):
    import subprocess
    import sys

    spec = Benchmark(
        **{**PRESETS["smoke"], "algos": ("td3",), "tasks": ("hopper",), "uncertainty": "3d"}
    )
    own = spec.fingerprints()
    _benchmark_with_one_run(tmp_path / "a", own)
    store.build_store(tmp_path / "a", own)  # its own: accepted
    _benchmark_with_one_run(tmp_path / "b", {**own, "protocol": "0123456789abcdef"})
    with pytest.raises(files.DamagedFile) as err:
        store.build_store(tmp_path / "b", own)
    one_line(err.value, "td3-hopper-3d-seed0", "another evaluation protocol", "0123456789abcdef")
    _benchmark_with_one_run(tmp_path / "c", {**own, "benchmark": "fedcba9876543210"})
    with pytest.raises(files.DamagedFile, match="another benchmark protocol"):
        store.build_store(tmp_path / "c", own)
    # a result written before fingerprints existed has none to compare: read as it is
    _benchmark_with_one_run(tmp_path / "d", {})
    store.build_store(tmp_path / "d", own)
    done = subprocess.run(
        [sys.executable, "-m", "rrls", "report", str(tmp_path / "b"), "--no-plots"],
        capture_output=True,
        text=True,
    )
    assert done.returncode == 2, done.stderr
    assert "Traceback" not in done.stderr and "another evaluation protocol" in done.stderr
    assert len(done.stderr.strip().splitlines()) == 1


# --- an evaluation's summary.json and a run's progress.json ---------------------------------
_EVAL = ROOT / "docs/results/halfcheetah/runs/td3-halfcheetah-3d-seed0/eval"


@pytest.mark.parametrize(("field", "bad"), cases(evaldir.SUMMARY_SCHEMA))
def test_a_hostile_evaluation_summary_is_refused_by_field(tmp_path, field, bad):
    import shutil

    shutil.copytree(_EVAL, tmp_path / "eval")
    summary = json.loads((_EVAL / "summary.json").read_text())
    files.write_checked_json(tmp_path / "eval" / "summary.json", {**summary, field: bad})
    with pytest.raises(SchemaError) as err:
        EvaluationResult.load(tmp_path / "eval")
    one_line(err.value, "summary.json", f"'{field}")


def test_the_shipped_evaluation_reads_back():
    assert EvaluationResult.load(_EVAL).worst_case == pytest.approx(94.45003996871871)


@pytest.mark.parametrize(
    "content", ["[]", '"x"', '{"phase": "train", "step": -1}', '{"phase": 3}', '{"sps": NaN}']
)
def test_a_hostile_progress_file_shows_nothing(tmp_path, content):
    from rrls.benchmark.pipeline import read_progress

    (tmp_path / rundir.PROGRESS).write_text(content)
    assert read_progress(tmp_path) is None
    (tmp_path / rundir.PROGRESS).write_text('{"phase": "train", "step": 5, "total": 9}')
    assert read_progress(tmp_path)["step"] == 5


# --- a policy file's header -----------------------------------------------------------------
@pytest.mark.parametrize(("field", "bad"), cases(HEADER_SCHEMA))
def test_a_hostile_policy_header_is_refused_by_field(tmp_path, field, bad):
    from rrls.evaluation.policies import MLPPolicy

    MLPPolicy.random(4, 1, (8,), seed=0).save(tmp_path / "p.npz")
    arrays = dict(np.load(tmp_path / "p.npz"))
    header = {**json.loads(bytes(arrays["header"]).decode()), field: bad}
    arrays["header"] = np.frombuffer(json.dumps(header).encode(), dtype=np.uint8)
    np.savez(tmp_path / "bad.npz", **arrays)
    with pytest.raises(ValueError) as err:
        MLPPolicy.load(tmp_path / "bad.npz")
    one_line(err.value, "bad.npz", f"'{field}")
