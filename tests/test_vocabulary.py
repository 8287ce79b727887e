"""One vocabulary across commands: ``--seeds``, ``--workers``, ``--physics`` labels, ``--yes``,
and help texts that describe, give defaults and list choices."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from rrls.cli import build_parser, main

ROOT = Path(__file__).resolve().parents[1]


def _still(obs: np.ndarray) -> np.ndarray:
    return np.zeros((len(obs), 1))


# -- --physics: recorded as typed, older files still read --------------------------------
def test_physics_is_recorded_as_the_flag_says(tmp_path: Path):
    from rrls.evaluation import evaluate

    kw = dict(mesh=2, episodes=1, workers=1, max_episode_steps=10, out_dir=tmp_path / "ev")
    result = evaluate(_still, "invertedpendulum", "1d", **kw)
    assert result.summary()["physics"] == "v5"
    assert json.loads((tmp_path / "ev" / "summary.json").read_text())["physics"] == "v5"


def test_an_evaluation_written_with_the_old_label_resumes(tmp_path: Path):
    from rrls.evaluation import evaluate

    kw = dict(mesh=2, episodes=1, workers=1, max_episode_steps=10, out_dir=tmp_path / "ev")
    first = evaluate(_still, "invertedpendulum", "1d", **kw)
    path = tmp_path / "ev" / "evaluation.json"
    config = json.loads(path.read_text())
    path.write_text(json.dumps({**config, "physics": "rrls-v5"}))  # as older rrls wrote it
    again = evaluate(_still, "invertedpendulum", "1d", **kw)  # no "different arguments"
    assert again.worst_case == first.worst_case


def test_old_benchmark_files_and_shipped_references_read_as_today():
    from rrls.experiments.reference import load_reference
    from rrls.experiments.spec import Spec, make_spec

    stored = make_spec("smoke").to_json()
    assert stored["physics"] == "v5"
    assert Spec.from_json({**stored, "physics": "rrls-v5"}) == make_spec("smoke")
    assert Spec.from_json({**stored, "physics": "paper-v4"}).physics == "paper"
    shipped = json.loads((ROOT / "rrls" / "experiments" / "quick_reference.json").read_text())
    assert shipped["physics"] == "rrls-v5"  # the file as shipped, untouched
    assert load_reference("quick").physics == "v5"
    for old in ROOT.glob("docs/results/*/benchmark.json"):
        assert Spec.from_json(json.loads(old.read_text())).physics == "v5", old


def test_main_is_importable():  # keeps `main` used while later sections grow
    assert callable(main) and build_parser(with_train=False).prog == "rrls"
