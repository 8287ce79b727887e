"""A path that runs into a loop of symbolic links is refused in one line, exit status 2, by every
command and in every argument naming a file or directory (``rrls train --out LOOP`` was a
``RuntimeError`` traceback from Python 3.11's ``Path.resolve``; others said ``File exists``)."""

from __future__ import annotations

from pathlib import Path

import pytest

from rrls.cli import main
from rrls.cli.app import build_parser
from rrls.cli.parsing import PATH_ARGUMENTS
from rrls.evaluation import MLPPolicy

ROOT = Path(__file__).resolve().parents[1]
RUN = str(ROOT / "docs/results/hopper-200k/runs/rarl-hopper-3d-seed0")
BENCH = str(ROOT / "docs/results/hopper-200k")
TRAIN = ["train", "--algo", "td3", "--task", "invertedpendulum", "--steps", "300"]
SUBMIT = ["--algo", "x", "--task", "hopper", "--seed", "0"]

#: every command, with LOOP (a link to itself) in each argument that names a path
CASES = [
    [*TRAIN, "--out", "LOOP"],
    [*TRAIN, "--out", "LOOP/run"],
    [*TRAIN, "--seeds", "0-1", "--out", "LOOP"],
    ["benchmark", "--preset", "smoke", "--out", "LOOP"],
    ["benchmark", "--preset", "smoke", "--out", "LOOP", "--dry-run"],
    ["evaluate", "p.npz", "--task", "hopper", "--out", "LOOP"],
    ["evaluate", "LOOP", "--task", "hopper"],
    ["evaluate-dynamic", RUN, "--out", "LOOP"],
    ["evaluate-dynamic", "LOOP"],
    ["report", "LOOP"],
    ["report", BENCH, "--reference", "LOOP"],
    ["report", BENCH, "--export-reference", "LOOP"],
    ["report", BENCH, "LOOP", "--out", "cross"],
    ["report", BENCH, BENCH, "--out", "LOOP"],
    ["benchmark", "--preset", "smoke", "--out", "b", "--protocol", "LOOP", "--dry-run"],
    ["submit", "LOOP", "p.npz", *SUBMIT],
    ["submit", BENCH, "LOOP", *SUBMIT],
    ["submit", BENCH, "p.npz", *SUBMIT, "--adversary", "LOOP/a.npz"],
    ["withdraw", "LOOP", "--algo", "x"],
    ["plot", "LOOP"],
    ["plot", BENCH, "--out", "LOOP"],
    ["quickstart", "--out", "LOOP"],
]


@pytest.mark.parametrize("argv", CASES, ids=lambda argv: " ".join(a for a in argv if "/" not in a))
def test_a_loop_of_links_is_refused_in_one_line(tmp_path, capsys, argv):
    (tmp_path / "LOOP").symlink_to("LOOP")  # the tests run in tmp_path
    MLPPolicy.random(11, 3, (8,), seed=0).save(tmp_path / "p.npz")
    try:
        code = main(argv)
    except SystemExit as stop:
        code = stop.code
    err = capsys.readouterr().err.strip()
    assert code == 2, err
    assert "\n" not in err and "Traceback" not in err, err
    assert err.startswith(f"rrls {argv[0]}: error: ") and "loop of symbolic links" in err, err
    assert "LOOP" in err
    assert not (tmp_path / "LOOP").is_dir() and (tmp_path / "LOOP").is_symlink()  # untouched


def test_every_path_argument_of_every_command_is_checked():
    parser = build_parser(with_train=True)
    named = set()
    for command, sub in parser.subcommands.items():
        for action in sub._actions:
            pathish = not action.option_strings or action.metavar in ("DIR", "FILE")
            pathish |= any(w in action.dest for w in ("out", "dir", "reference", "adversary"))
            if pathish and action.dest != "help":
                assert action.dest in PATH_ARGUMENTS, (command, action.dest)
                named.add(action.dest)
    assert named == set(PATH_ARGUMENTS)  # none listed that no command has


def test_the_library_refuses_a_loop_without_a_runtime_error(tmp_path):
    pytest.importorskip("torch")
    from rrls.agents import train
    from rrls.agents.config import TrainConfig

    (tmp_path / "LOOP").symlink_to("LOOP")
    config = TrainConfig(algo="td3", task="invertedpendulum", steps=300, out=str(tmp_path / "LOOP"))
    with pytest.raises(OSError) as err:
        train(config)
    assert "LOOP" in str(err.value)
