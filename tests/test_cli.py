"""The command line: `rrls check`, `--version`, `python -m rrls`."""

from __future__ import annotations

import pathlib
import subprocess
import sys

import pytest

import rrls
from rrls.cli import main

ROOT = pathlib.Path(__file__).resolve().parents[1]


def test_check_prints_a_table_for_every_point(capsys):
    assert main(["check", "--task", "invertedpendulum", "--steps", "5"]) == 0
    out = capsys.readouterr().out
    # nominal + 2 (1d) + 4 (2d) + 4 (rarl) corners
    assert "11 ok, 0 failed" in out
    assert "invertedpendulum  2d" in out and "31,11" in out


def test_version_and_module_entry_point():
    out = subprocess.run(
        [sys.executable, "-m", "rrls", "--version"], capture_output=True, text=True, cwd=ROOT
    )
    assert out.returncode == 0 and out.stdout.strip() == f"rrls {rrls.__version__}"


def test_unknown_task_is_a_clear_error(capsys):
    assert main(["check", "--task", "cartpole"]) == 2  # one line, no usage block
    err = capsys.readouterr().err
    assert "valid tasks" in err and len(err.strip().splitlines()) == 1


def test_flags_are_never_abbreviated_and_an_unknown_one_is_named_with_a_suggestion(capsys):
    from rrls.cli import main

    # argparse would have taken --mes as --mesh; rrls refuses, naming the command and the flag
    assert main(["evaluate", "x", "--mes", "2"]) == 2
    err = capsys.readouterr().err.strip()
    hint = "(did you mean --mesh?); see rrls evaluate --help"
    assert err == f"rrls evaluate: error: unknown option --mes {hint}"
    assert main(["benchmark", "--preset", "quick", "--out", "x", "--dryrun"]) == 2
    assert "did you mean --dry-run?" in capsys.readouterr().err
    assert main(["evaluate", "x", "--zzz"]) == 2
    err = capsys.readouterr().err.strip()
    assert (
        err.startswith("rrls evaluate: error: unknown option --zzz;") and len(err.splitlines()) == 1
    )


def test_train_warns_when_the_budget_ends_inside_the_warm_up(tmp_path, capsys):
    pytest.importorskip("torch")
    from rrls.cli import main

    base = ["train", "--algo", "td3", "--task", "invertedpendulum", "--eval-every", "0"]
    assert main([*base, "--steps", "40", "--out", str(tmp_path / "a")]) == 0
    err = capsys.readouterr().err
    assert "--steps 40 <= the warm-up of 25000 random steps" in err and "untrained" in err
    small = ["--hidden", "8", "8", "--batch-size", "8", "--learning-starts", "20"]
    assert main([*base, "--steps", "40", *small, "--out", str(tmp_path / "b")]) == 0
    assert "warm-up" not in capsys.readouterr().err  # 20 updates were made


def test_evaluate_default_folders_are_per_policy(tmp_path, monkeypatch):
    from rrls.evaluation.policies import MLPPolicy

    monkeypatch.chdir(tmp_path)
    for seed in (0, 1):
        MLPPolicy.random(4, 1, (8,), seed=seed).save(tmp_path / f"pol{seed}.npz")
        args = ["evaluate", f"pol{seed}.npz", "--task", "invertedpendulum", "--mesh", "2"]
        assert main([*args, "--episodes", "1", "--uncertainty", "1d", "--workers", "1"]) == 0
    folders = sorted(p.name for p in (tmp_path / "evaluations").iterdir())
    assert folders == [
        "pol0-invertedpendulum-1d-mesh2-ep1-seed0",
        "pol1-invertedpendulum-1d-mesh2-ep1-seed0",
    ]


def test_suggested_commands_quote_paths_with_spaces(tmp_path, capsys):
    """A command rrls prints for the user to run works when pasted: paths are shell-quoted."""
    import shlex

    out = tmp_path / "my runs" / "td3 seed0"
    argv = ["train", "--algo", "td3", "--task", "invertedpendulum", "--steps", "200"]
    assert main([*argv, "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    line = printed[printed.index("rrls evaluate") :].split(")")[0]
    assert shlex.split(line) == ["rrls", "evaluate", str(out)]
