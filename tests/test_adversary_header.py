"""An ``adversary.npz``'s metadata is read against its schema (``ADVERSARY_SCHEMA``): a missing
``task`` was a ``KeyError: 'task'`` and ``alpha: null`` a ``TypeError`` traceback in
``rrls evaluate-dynamic``; every missing or ill-typed field is now one line naming the file, the
field and what is valid, before any episode is played."""

from __future__ import annotations

import json
import shutil
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from test_file_schemas import cases, one_line

from rrls.cli import main
from rrls.evaluation import MLPPolicy, evaluate_run_dynamic
from rrls.evaluation.dynamic import ADVERSARY_SCHEMA, GAME_SCHEMA, check_adversary
from rrls.schema import SchemaError

ROOT = Path(__file__).resolve().parents[1]
RUNS = ROOT / "docs/results/hopper-200k/runs"


def _run_with_adversary(tmp_path: Path, change: dict[str, Any], drop: str | None = None) -> Path:
    """A copy of a shipped NR-MDP run whose adversary's metadata has ``change`` (and lacks
    ``drop``), the file otherwise as rrls wrote it."""
    run = tmp_path / "run"
    shutil.copytree(RUNS / "nrmdp-hopper-3d-seed0", run)
    path = run / "adversary.npz"
    arrays = dict(np.load(path))
    header = json.loads(bytes(arrays["header"]).decode())
    header["metadata"] = {**header["metadata"], **change}
    header["metadata"].pop(drop, None)
    arrays["header"] = np.frombuffer(json.dumps(header).encode(), dtype=np.uint8)
    np.savez(path, **arrays)
    return run


def test_every_shipped_adversary_matches_the_schema():
    paths = sorted(ROOT.glob("docs/results/**/adversary.npz"))
    assert len(paths) >= 12
    for path in paths:
        meta = MLPPolicy.load(path).metadata
        assert check_adversary(meta, str(path)) == meta


@pytest.mark.parametrize(("field", "bad"), cases(ADVERSARY_SCHEMA))
def test_an_ill_typed_adversary_field_is_refused_by_name(tmp_path, field, bad):
    run = _run_with_adversary(tmp_path, {field: bad})
    with pytest.raises(SchemaError) as err:
        evaluate_run_dynamic(run, episodes=1, workers=0)
    one_line(err.value, "adversary.npz", f"'metadata.{field}", "valid: ")


def test_a_missing_task_is_refused_by_name(tmp_path):
    run = _run_with_adversary(tmp_path, {}, drop="task")
    with pytest.raises(SchemaError) as err:
        evaluate_run_dynamic(run, episodes=1, workers=0)
    one_line(err.value, "adversary.npz", "'metadata.task' is missing", "valid: a string")


def test_an_adversary_from_elsewhere_need_not_name_its_task():
    assert check_adversary({"game": "nr", "alpha": 0.2}, "a.npz", GAME_SCHEMA)
    with pytest.raises(SchemaError, match="'metadata.alpha' is None"):
        check_adversary({"game": "nr", "alpha": None}, "a.npz", GAME_SCHEMA)
    with pytest.raises(SchemaError, match="'metadata.task' is missing"):
        check_adversary({"game": "nr"}, "a.npz")
    with pytest.raises(SchemaError, match="it holds|valid: an object"):
        check_adversary([1], "a.npz")


@pytest.mark.parametrize(
    ("change", "drop", "named"),
    [
        ({}, "task", "'metadata.task' is missing"),
        ({"alpha": None}, None, "'metadata.alpha' is None"),
        ({"game": "bogus"}, None, "'metadata.game' is 'bogus'"),
        ({"history": "3"}, None, "'metadata.history' is '3'"),
    ],
)
def test_evaluate_dynamic_refuses_a_bad_adversary_in_one_line(
    tmp_path, capsys, change, drop, named
):
    run = _run_with_adversary(tmp_path, change, drop)
    try:
        code = main(["evaluate-dynamic", str(run), "--episodes", "1", "--workers", "0"])
    except SystemExit as stop:
        code = stop.code
    err = capsys.readouterr().err.strip()
    assert code == 2, err
    assert "\n" not in err and "Traceback" not in err, err
    assert err.startswith("rrls evaluate-dynamic: error: ") and named in err, err
    assert str(run / "adversary.npz") in err
