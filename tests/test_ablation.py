"""benchmarks/ablation.py: the authors' variants pair with the reference's runs by seed."""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path

import pytest

pytest.importorskip("torch")

ROOT = Path(__file__).resolve().parent.parent


@pytest.fixture(scope="module")
def ablation():
    spec = importlib.util.spec_from_file_location("ablation", ROOT / "benchmarks/ablation.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    module.register()  # as the script does when it runs
    yield module
    from rrls.algorithms import ALGORITHMS

    for info in module.VARIANTS.values():  # other tests see the built-in table only
        ALGORITHMS.pop(info.name, None)


def _run(folder: Path, worst: float, average: float, nominal: list[float]) -> None:
    folder.mkdir(parents=True)
    result = {"worst_case": worst, "average_case": average, "steps": 300_000}
    (folder / "result.json").write_text(json.dumps(result))
    lines = ["step,metric,value"]
    lines += [f"{10_000 * (i + 1)},eval/nominal_return,{v}" for i, v in enumerate(nominal)]
    lines += ["20000,charts/episode_return,-1.0"]
    (folder / "scalars.csv").write_text("\n".join(lines) + "\n")


def test_variants_are_registered_rows_the_benchmark_accepts(ablation):
    from rrls.algorithms import plays_adversary, warmup

    names = {algo: info.name for algo, info in ablation.VARIANTS.items()}
    assert names == {"nrmdp": "nrmdp-tessler", "m2td3": "m2td3-authors"}
    assert plays_adversary("nrmdp-tessler") and not plays_adversary("m2td3-authors")
    assert warmup("m2td3-authors") == warmup("m2td3") == 100_000
    from rrls.agents.lookup import algorithm

    tessler = algorithm("nrmdp-tessler").Config()
    assert tessler.normalize_obs and tessler.critic_weight_decay == 1e-2
    authors = algorithm("m2td3-authors").Config()
    assert not authors.clip_exploration and authors.same_start
    from rrls.benchmark.grid import make_spec

    spec = make_spec("halfcheetah", algos="nrmdp-tessler,m2td3-authors", seeds=2)
    assert spec.warmup("m2td3-authors") == 100_000 and spec.warmup("nrmdp-tessler") == 25_000


def test_table_pairs_each_variant_run_with_the_reference_run_of_its_seed(ablation, tmp_path):
    ref, out = tmp_path / "reference", tmp_path / "variants"
    _run(ref / "nrmdp-halfcheetah-3d-seed0", -300.0, 2000.0, [10.0, 5000.0])
    _run(ref / "nrmdp-halfcheetah-3d-seed1", -500.0, 1000.0, [7000.0])
    _run(ref / "nrmdp-halfcheetah-3d-seed2", 0.0, 0.0, [0.0])  # no variant run: left out
    _run(out / "runs" / "nrmdp-tessler-halfcheetah-3d-seed0", -100.0, 3000.0, [6000.0])
    _run(out / "runs" / "nrmdp-tessler-halfcheetah-3d-seed1", -300.0, 2000.0, [8000.0])
    (out / "runs" / "m2td3-authors-halfcheetah-3d-seed0").mkdir()  # not finished: left out
    frame = ablation.collect(out, ref)
    assert sorted(frame.seed.unique()) == [0, 1] and set(frame.algorithm) == {"nrmdp"}
    row = frame[(frame.variant == "rrls") & (frame.seed == 0)].iloc[0]
    assert (row.worst_case, row.nominal) == (-300.0, 5000.0)  # the last nominal evaluation
    text = ablation.table(frame)
    assert (
        "| NR-MDP (Tessler's code) | worst case | 2 | -400 ± 141 | -200 ± 141 | 0.50 | +200, +200 |"
        in text
    )
    assert "| average case | 2 | 1500 ± 707 | 2500 ± 707 | 1.67 | +1000, +1000 |" in text
    one = ablation.table(frame[frame.seed == 0])  # one seed: its value, no spread
    assert "| final nominal return | 1 | 5000 | 6000 | 1.20 | +1000 |" in one and "±" not in one
