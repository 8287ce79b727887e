"""Every JSON file rrls reads goes through one reader (``rrls.files.loads_json``) with a depth
and a size limit: a file nested 100 000 levels deep (Python's parser recurses: a
``RecursionError`` traceback before) or larger than the limit is refused in one line naming
it, by each reader and by each command that reads one."""

from __future__ import annotations

import io
import json
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pytest
from test_file_schemas import RESULT  # a valid result.json, beside this file

from rrls import files, rundir
from rrls.benchmark import benchfile, store
from rrls.benchmark.grid import PRESETS, Benchmark
from rrls.cli import main
from rrls.evaluation import EvaluationResult, MLPPolicy
from rrls.files import MAX_JSON_BYTES, MAX_JSON_DEPTH, loads_json, read_json, read_limited
from rrls.report.reference import ReferenceError, load_reference
from rrls.schema import JsonError

ROOT = Path(__file__).resolve().parents[1]
LEVELS = 100_000

#: JSON nested 100 000 levels deep: a list, an object, and an object whose one field is deep
DEEP = {
    "list": "[" * LEVELS + "]" * LEVELS,
    "object": '{"a":' * LEVELS + "1" + "}" * LEVELS,
    "field": '{"algorithm": ' + "[" * LEVELS + "]" * LEVELS + "}",
}
SHAPES = sorted(DEEP)


def one_line(text: str, *words: str) -> None:
    text = text.strip()
    assert text and "\n" not in text and "Traceback" not in text, text
    for word in words:
        assert word in text, (word, text)


def _cli(argv: list[str], capsys) -> str:
    """``rrls ARGV``'s stderr, which must be one line, with exit status 2."""
    capsys.readouterr()
    try:
        code = main(argv)
    except SystemExit as stop:
        code = stop.code
    err = capsys.readouterr().err
    assert code == 2, err
    one_line(err)
    return err


# --- the reader itself -----------------------------------------------------------------------
@pytest.mark.parametrize("shape", SHAPES)
def test_deep_json_is_refused_in_one_line_not_a_recursion_error(shape):
    with pytest.raises(JsonError) as err:
        loads_json(DEEP[shape], "x.json")
    one_line(str(err.value), "x.json", f"more than {MAX_JSON_DEPTH} levels")
    assert not err.value.syntax


def test_the_depth_limit_is_the_stated_one_whatever_the_recursion_limit():
    at = "[" * MAX_JSON_DEPTH + "]" * MAX_JSON_DEPTH
    assert loads_json(at, "x") is not None  # as deep as allowed: read
    beyond = '{"a": ' + at + "}"
    with pytest.raises(JsonError, match="nested more than"):
        loads_json(beyond, "x")  # one level more: refused although Python parses it
    shipped = sorted(ROOT.glob("docs/results/**/summary.json"))[:3]
    for path in [*shipped, ROOT / "rrls/report/halfcheetah_reference.json"]:
        assert loads_json(path.read_bytes(), str(path))  # rrls's own files: well within


@pytest.mark.parametrize(
    ("data", "words"),
    [
        (b"\xff{}", "not UTF-8"),
        ("{'a': 1}", "not valid JSON"),
        (3, "valid: JSON text"),
        (None, "valid: JSON text"),
    ],
)
def test_what_is_not_json_text_is_refused_naming_the_file(data, words):
    with pytest.raises(JsonError) as err:
        loads_json(data, "x.json")
    one_line(str(err.value), "x.json", words)


def test_a_file_above_the_size_limit_is_refused_before_it_is_read_whole(tmp_path):
    path = tmp_path / "big.json"
    path.write_text("[" + "1," * 50 + "1]")
    with pytest.raises(JsonError) as err:
        read_limited(path, limit=64)
    one_line(str(err.value), "big.json", "more than 64 bytes")
    assert read_json(path) == [1] * 51
    with pytest.raises(JsonError, match=f"valid: at most {MAX_JSON_BYTES:,} bytes"):
        loads_json(" " * (MAX_JSON_BYTES + 1), "x.json")
    path.write_bytes(b" " * (MAX_JSON_BYTES + 1))  # a sealed results file too
    files.write_checked(path, path.read_bytes())
    with pytest.raises(files.DamagedFile, match="big.json is damaged .*more than"):
        files.read_checked_json(path)


# --- each file kind, through its reader ------------------------------------------------------


def _deep(path: Path, shape: str) -> Path:
    """``path`` holding the deep JSON, sealed as rrls seals it (the seal is no defence)."""
    return files.write_checked(path, DEEP[shape].encode())


@pytest.mark.parametrize("shape", SHAPES)
def test_every_results_file_reader_refuses_deep_json(tmp_path, shape):
    readers = {
        benchfile.spec_path(tmp_path): lambda: benchfile.read_spec(tmp_path),
        tmp_path / rundir.RESULT: lambda: store.read_result(tmp_path),
        tmp_path / rundir.RUN_JSON: lambda: rundir.read_run_json(tmp_path),
        tmp_path / "eval" / "summary.json": lambda: EvaluationResult.load(tmp_path / "eval"),
    }
    for path, read in readers.items():
        _deep(path, shape)
        with pytest.raises(ValueError) as err:
            read()
        one_line(str(err.value), str(path), "is damaged", "levels deep")
    (tmp_path / rundir.POLICY).write_bytes(b"")
    assert rundir.finished_steps(tmp_path) is None  # a damaged run.json: not a finished run


@pytest.mark.parametrize("shape", SHAPES)
def test_a_deep_reference_file_is_refused(tmp_path, shape):
    path = tmp_path / "ref.json"
    path.write_text(DEEP[shape])
    with pytest.raises(ReferenceError) as err:
        load_reference(path)
    one_line(str(err.value), str(path), "levels deep")


@pytest.mark.parametrize("shape", SHAPES)
def test_a_deep_progress_file_shows_nothing(tmp_path, shape):
    from rrls.benchmark.pipeline import read_progress

    (tmp_path / rundir.PROGRESS).write_text(DEEP[shape])
    assert read_progress(tmp_path) is None


def _policy_with_header(path: Path, header: str) -> Path:
    MLPPolicy.random(11, 3, (8,), seed=0).save(path)
    arrays = dict(np.load(path))
    arrays["header"] = np.frombuffer(header.encode(), dtype=np.uint8)
    np.savez(path, **arrays)
    return path


@pytest.mark.parametrize("shape", SHAPES)
def test_a_deep_policy_header_is_refused(tmp_path, shape):
    path = _policy_with_header(tmp_path / "p.npz", DEEP[shape])
    with pytest.raises(ValueError) as err:
        MLPPolicy.load(path)
    one_line(str(err.value), "p.npz", "levels deep")


def test_a_deep_budget_in_the_store_is_refused():
    from rrls.report.summary import provenance

    runs = pd.DataFrame(
        {"source": ["submitted"], "algorithm": ["x"], "task": ["hopper"], "seed": [0]}
        | {"steps": [0], "budget": [DEEP["object"]]}
    )
    with pytest.raises(ValueError) as err:
        provenance({"evaluations": pd.DataFrame(), "runs": runs})
    one_line(str(err.value), "budget", "levels deep")
    runs["budget"] = ["[1]"]
    with pytest.raises(ValueError, match="valid: a JSON object"):
        provenance({"evaluations": pd.DataFrame(), "runs": runs})


# --- each command that reads one -------------------------------------------------------------
def _benchmark(root: Path) -> Path:
    """A benchmark of one TD3 run on hopper, written as rrls writes it (no training)."""
    spec = Benchmark(**{**PRESETS["smoke"], "algos": ("td3",), "tasks": ("hopper",)})
    spec = Benchmark(**{**spec.to_json(), "uncertainty": "3d"})
    benchfile.write_spec(root, spec)
    run = root / "runs" / "td3-hopper-3d-seed0"
    (run / "eval").mkdir(parents=True)
    episodes = pd.DataFrame(
        {"point": [0, 1], "episode": [0, 0], "seed": [1, 2], "return": [1.0, 3.0]}
        | {"length": [10, 10], "terminated": [False, False], "diverged": [False, False]}
    )
    files.write_checked_table(run / "eval" / "episodes.csv", episodes)
    store.write_result(run, {**RESULT, "steps": spec.steps, **spec.fingerprints()})
    return run


def _submitted(root: Path) -> Path:
    """A submitted run of ``mine`` beside the benchmark's own."""
    run = root / "runs" / "mine-hopper-3d-seed0"
    (run / "eval").mkdir(parents=True)
    own = root / "runs" / "td3-hopper-3d-seed0" / "eval" / "episodes.csv"
    files.write_checked_table(run / "eval" / "episodes.csv", files.read_checked_table(own))
    store.write_result(run, {**RESULT, "algorithm": "mine", "submitted": {"kind": "npz"}})
    return run


@pytest.mark.parametrize("shape", SHAPES)
@pytest.mark.parametrize("name", ["benchmark.json", "result.json"])
def test_report_withdraw_and_submit_refuse_a_deep_file_in_one_line(tmp_path, capsys, shape, name):
    root = tmp_path / "bench"
    run = _benchmark(root)
    _submitted(root)
    path = _deep(root / "benchmark.json" if name == "benchmark.json" else run / name, shape)
    policy = tmp_path / "p.npz"
    MLPPolicy.random(11, 3, (8,), seed=0).save(policy)
    err = _cli(["report", str(root), "--no-plots"], capsys)
    assert str(path) in err and "levels deep" in err
    err = _cli(["withdraw", str(root), "--algo", "mine"], capsys)
    assert str(path) in err and "levels deep" in err
    assert (root / "runs" / "mine-hopper-3d-seed0").is_dir()  # nothing withdrawn
    if name == "benchmark.json":  # submit reads the protocol before anything else
        err = _cli(["submit", str(root), str(policy), "--algo", "x", "--task", "hopper",
                    "--seed", "0"], capsys)  # fmt: skip
        assert str(path) in err and "levels deep" in err


@pytest.mark.parametrize("shape", SHAPES)
def test_report_refuses_a_deep_reference_and_a_deep_run_json(tmp_path, capsys, shape):
    root = tmp_path / "bench"
    run = _benchmark(root)
    ref = tmp_path / "ref.json"
    ref.write_text(DEEP[shape])
    err = _cli(["report", str(root), "--no-plots", "--reference", str(ref)], capsys)
    assert str(ref) in err and "levels deep" in err
    path = _deep(run / rundir.RUN_JSON, shape)
    out = tmp_path / "exported.json"
    err = _cli(["report", str(root), "--no-plots", "--export-reference", str(out)], capsys)
    assert str(path) in err and "levels deep" in err
    assert not out.exists()


@pytest.mark.parametrize("shape", SHAPES)
def test_submit_and_evaluate_refuse_a_deep_policy_header(tmp_path, capsys, shape):
    root = tmp_path / "bench"
    _benchmark(root)
    policy = _policy_with_header(tmp_path / "p.npz", DEEP[shape])
    err = _cli(["submit", str(root), str(policy), "--algo", "x", "--task", "hopper",
                "--seed", "0"], capsys)  # fmt: skip
    assert "p.npz" in err and "levels deep" in err
    err = _cli(["evaluate", str(policy), "--task", "hopper", "--mesh", "2"], capsys)
    assert "p.npz" in err and "levels deep" in err


def _checkpoint(out: Path, config: str, **state: Any) -> None:
    import torch

    buf = io.BytesIO()
    torch.save({"learner": {}, "config": config, "step": 0, "episodes": 0, **state}, buf)
    out.mkdir(parents=True, exist_ok=True)
    files.write_sealed(out / rundir.CHECKPOINT, buf.getvalue())


@pytest.mark.parametrize("shape", SHAPES)
def test_train_resume_refuses_a_deep_checkpoint_config_and_a_deep_run_json(tmp_path, capsys, shape):
    pytest.importorskip("torch")
    out = tmp_path / "run"
    _checkpoint(out, DEEP[shape])
    (out / rundir.POLICY).write_bytes(b"")  # with a deep run.json: not finished, resumed
    path = _deep(out / rundir.RUN_JSON, shape)
    argv = ["train", "--algo", "td3", "--task", "invertedpendulum", "--steps", "300"]
    err = _cli([*argv, "--out", str(out), "--resume"], capsys)
    assert str(out / rundir.CHECKPOINT) in err and "levels deep" in err
    assert path.exists()  # refused before anything was removed
    _checkpoint(out, json.dumps([1]))
    err = _cli([*argv, "--out", str(out), "--resume"], capsys)
    assert "its config is not an object" in err


@pytest.mark.parametrize("shape", SHAPES)
def test_train_refuses_a_deep_hyper_parameter_and_reads_plain_text_as_text(tmp_path, capsys, shape):
    pytest.importorskip("torch")
    argv = ["train", "--algo", "td3", "--task", "invertedpendulum", "--steps", "300"]
    argv += ["--out", str(tmp_path / "run")]
    err = _cli([*argv, "--hyper", f"x={DEEP[shape]}"], capsys)
    assert "--hyper x" in err and "levels deep" in err
    assert not (tmp_path / "run").exists()
    err = _cli([*argv, "--hyper", "x=[not json"], capsys)  # text: refused later, by name
    assert "td3 has no hyper-parameter 'x'" in err
