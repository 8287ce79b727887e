"""Outside probes of damaged files (issue 26): results files are sealed like checkpoints
(``NAME.sha256`` beside each); one flipped byte is a one-line error naming the file, never a
report with wrong numbers; older unsealed files are still read."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest
from conftest import stopping_at

torch = pytest.importorskip("torch")
pytest.importorskip("scipy")

from rrls import files, rundir  # noqa: E402
from rrls.cli import main  # noqa: E402

#: the long end-to-end tier (.ci/run runs it after the default suite)
pytestmark = pytest.mark.e2e

SMALL = ["--hidden", "8", "8", "--batch-size", "16", "--learning-starts", "50"]


def _train(out: Path, *extra: str) -> int:
    args = ["train", "--algo", "td3", "--task", "invertedpendulum", "--steps", "300"]
    args += ["--eval-every", "100", "--checkpoint-every", "100", "--out", str(out)]
    return main([*args, *SMALL, *extra])


def _flip(path: Path, where: float = 0.5, to: int | None = None) -> None:
    """Change one byte of ``path`` (at a fraction of its length; ``to``: the new byte)."""
    data = bytearray(path.read_bytes())
    i = min(int(len(data) * where), len(data) - 1)
    data[i] = to if to is not None else data[i] ^ 0x01
    path.write_bytes(bytes(data))


def _one_line(capsys) -> str:
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "Traceback" not in err, err
    return err


@pytest.mark.parametrize("to", [0xFF, None], ids=["not-utf8", "one-bit"])
def test_a_damaged_curve_file_stops_a_resume_naming_it(tmp_path, capsys, to):
    out = tmp_path / "run"
    with stopping_at(200):
        assert _train(out) == 3
    scalars = out / rundir.SCALARS
    assert files.seal_path(scalars).exists()
    _flip(scalars, 0.6, to)
    capsys.readouterr()
    assert _train(out, "--resume") == 2
    err = _one_line(capsys)
    assert str(scalars) in err and "damaged" in err


def test_curves_written_after_the_last_checkpoint_are_dropped_on_resume(tmp_path):
    out = tmp_path / "run"
    with stopping_at(200):
        assert _train(out) == 3
    scalars = out / rundir.SCALARS
    with open(scalars, "a") as f:  # a killed run's rows past its checkpoint, half written
        f.write("250,charts/episode_return,1.0\n260,charts/epi")
    assert _train(out, "--resume") == 0
    lines = scalars.read_text().splitlines()
    assert not any(ln.startswith(("250,", "260,")) for ln in lines)
    files.read_checked(scalars)  # sealed again, whole


@pytest.fixture(scope="module")
def finished(tmp_path_factory) -> Path:
    """A smoke benchmark of TD3 (one run, finished): every results file written once."""
    from rrls.benchmark.grid import make_spec
    from rrls.benchmark.runner import benchmark

    root = tmp_path_factory.mktemp("bench")
    assert benchmark(root, make_spec("smoke", algos="td3"), 1) == 0
    return root


@pytest.fixture
def bench(finished, tmp_path) -> Path:
    copy = tmp_path / "bench"
    shutil.copytree(finished, copy)
    return copy


def _run(root: Path) -> Path:
    return next((root / "runs").glob("td3-*"))


def _episodes(root: Path) -> Path:
    return next((_run(root) / "eval").glob("episodes.*"))


@pytest.mark.parametrize(
    "name", ["benchmark.json", "result.json", "scalars.csv", "episodes", "summary.json"]
)
@pytest.mark.parametrize("where", [0.3, 0.5, 0.9])
def test_one_flipped_byte_in_a_results_file_is_named_by_the_report(bench, capsys, name, where):
    path = {
        "benchmark.json": bench / "benchmark.json",
        "result.json": _run(bench) / "result.json",
        "scalars.csv": _run(bench) / "scalars.csv",
        "episodes": _episodes(bench),
        "summary.json": _run(bench) / "eval" / "summary.json",
    }[name]
    assert files.seal_path(path).exists()
    _flip(path, where)
    capsys.readouterr()
    if name == "summary.json":  # read by `rrls evaluate`'s loader, not by the report
        from rrls.evaluation import EvaluationResult

        with pytest.raises(files.DamagedFile, match="summary.json is damaged"):
            EvaluationResult.load(path.parent)
        return
    assert main(["report", str(bench), "--no-plots"]) == 2
    err = _one_line(capsys)
    assert str(path) in err and "damaged" in err
    assert not (bench / "report" / "summary.json").exists()  # no report of wrong numbers


def test_a_flipped_return_never_reaches_the_report(bench, capsys):
    """The issue's case: a byte of a stored return changed, result.json intact."""
    from rrls.files import table_bytes

    path = _episodes(bench)
    frame = files.read_checked_table(path)
    frame.loc[0, "return"] = -65536.0  # what a flipped exponent bit made of a return
    path.write_bytes(table_bytes(path, frame))  # rewritten without its seal's knowledge
    assert main(["report", str(bench), "--no-plots"]) == 2
    assert str(path) in _one_line(capsys)


def test_a_damaged_seal_is_damage_too(bench, capsys):
    side = files.seal_path(_run(bench) / "result.json")
    side.write_text("not a digest\n")
    assert main(["report", str(bench), "--no-plots"]) == 2
    assert "result.json.sha256 is damaged" in _one_line(capsys)


def test_older_unsealed_files_are_still_read(bench, capsys):
    for side in bench.rglob("*.sha256"):
        side.unlink()
    assert main(["report", str(bench), "--no-plots"]) == 0
    summary = json.loads((bench / "report" / "summary.json").read_text())
    assert "td3" in next(iter(summary["results"].values()))


def test_sealed_files_check_with_sha256sum_by_hand(bench):
    import hashlib

    path = _run(bench) / "result.json"
    digest, name = files.seal_path(path).read_text().split()
    assert name == "result.json"
    assert digest == hashlib.sha256(path.read_bytes()).hexdigest()
