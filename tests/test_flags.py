"""One meaning per flag in every command, and the docs and ``--help`` agree with the parsers.

The rule: ``--seed S``/``--seeds SEEDS`` are training seeds (train; submit and withdraw: the seed
a policy was trained with; benchmark, quickstart); ``--episode-seed S`` is the root of an
evaluation's episode seeds (evaluate, evaluate-dynamic, check), whose old ``--seed`` still
parses for one release with a one-line warning; ``--workers N`` is N worker processes, 0 none
(the work runs in this process; benchmark, whose runs each need a process, refuses it),
default the machine's cores (train: what pays off).
"""

from __future__ import annotations

import argparse
import re
from pathlib import Path

import pytest

from rrls.cli import build_parser, main

REPO = Path(__file__).resolve().parents[1]
COMMANDS = "train|evaluate-dynamic|evaluate|benchmark|report|submit|withdraw|quickstart|plot|check"
#: ``rrls COMMAND ...`` as the docs and help texts show it (not a path such as ``rrls/cli``)
LINE = re.compile(rf"(?<![\w/.-])rrls ({COMMANDS})(?![\w-])(.*)")
FLAG = re.compile(r"(?<![\w-])--[a-z][a-z0-9-]*")
SPAN = re.compile(r"`([^`\n]+)`")


@pytest.fixture(scope="module")
def parser() -> argparse.ArgumentParser:
    pytest.importorskip("torch")  # `train`'s options come from its dataclasses
    return build_parser(with_train=True)


def _options(parser: argparse.ArgumentParser, command: str) -> dict[str, argparse.Action]:
    sub = parser.subcommands[command]
    return {flag: action for action in sub._actions for flag in action.option_strings}


def _advertised(parser: argparse.ArgumentParser, command: str) -> set[str]:
    """The flags ``rrls COMMAND --help`` shows: deprecated spellings are hidden."""
    return {f for f, a in _options(parser, command).items() if a.help != argparse.SUPPRESS}


def _shown(text: str) -> list[tuple[int, str, list[str]]]:
    """``(line, command, flags)`` of every ``rrls COMMAND ...`` of a Markdown text: each line of
    a code block (comments and what follows a pipe cut off) and each inline code span."""
    found, block = [], False
    for number, line in enumerate(text.splitlines(), 1):
        if line.lstrip().startswith("```"):
            block = not block
            continue
        for piece in [line.split(" #")[0]] if block else SPAN.findall(line):
            for match in LINE.finditer(piece):
                rest = re.split(r"\s(?:\||&&|;)\s", match.group(2))[0]
                found.append((number, match.group(1), FLAG.findall(rest)))
    return found


def _docs() -> list[Path]:
    return [REPO / "README.md", *sorted((REPO / "docs").rglob("*.md"))]


def test_every_flag_the_docs_show_exists_in_its_command_and_is_not_deprecated(parser):
    wrong, seen = [], 0
    for path in _docs():
        for number, command, flags in _shown(path.read_text(encoding="utf-8")):
            valid = _advertised(parser, command)
            seen += len(flags)
            wrong += [
                f"{path.relative_to(REPO)}:{number}: rrls {command} {flag}"
                for flag in flags
                if flag not in valid
            ]
    assert wrong == []
    assert seen > 100  # the scan reads the docs' commands, code blocks and inline spans alike


def test_the_scan_finds_flags_in_blocks_and_spans_and_skips_comments():
    text = "```bash\nrrls evaluate P --seed 0  # --nope\n```\nsee `rrls train --steps 1e4` and\n"
    assert _shown(text) == [(2, "evaluate", ["--seed"]), (4, "train", ["--steps"])]


def test_no_doc_shows_seeds_as_a_count():
    """``--seeds`` takes a list or range everywhere (a lone 3 is seed 3): ``--seeds N`` reads as
    a count, and benchmark and quickstart refuse a bare number."""
    grid = re.compile(r"rrls (benchmark|quickstart)\b[^`#]*--seeds \d+(?![\d,-])")
    hits = []
    for path in _docs():
        for number, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
            if re.search(r"--seeds N\b", line) or grid.search(line):
                hits.append(f"{path.relative_to(REPO)}:{number}")
    assert hits == []


def _help_flags(text: str) -> tuple[list[tuple[str, str]], list[str]]:
    """A help text's ``rrls OTHER --flag`` mentions (checked against OTHER) and its bare flags
    (checked against its own command)."""
    other = []
    for span in [*SPAN.findall(text)]:
        for match in LINE.finditer(span):
            other += [(match.group(1), f) for f in FLAG.findall(match.group(2))]
            text = text.replace(span, "")
    return other, FLAG.findall(text)


def test_every_flag_a_help_text_names_exists_where_it_says(parser):
    wrong = []
    for command, sub in parser.subcommands.items():
        texts = [sub.description or ""]
        texts += [a.help for a in sub._actions if a.help and a.help != argparse.SUPPRESS]
        for text in texts:
            other, own = _help_flags(text)
            wrong += [f"{command}: {f}" for f in own if f not in _advertised(parser, command)]
            wrong += [
                f"{command}: rrls {c} {f}" for c, f in other if f not in _advertised(parser, c)
            ]
    assert wrong == []
    top = parser.description  # the one vocabulary the top-level help announces
    for flag in FLAG.findall(top):
        assert any(flag in _advertised(parser, c) for c in parser.subcommands), flag


# -- one meaning per flag --------------------------------------------------------------------
def test_seed_names_a_training_seed_in_every_command_that_has_it(parser):
    having = [c for c in parser.subcommands if "--seed" in _advertised(parser, c)]
    assert sorted(having) == ["submit", "train", "withdraw"]
    for command in having:
        assert "training seed" in _options(parser, command)["--seed"].help, command
    for command in ("benchmark", "quickstart", "train"):
        assert "training seeds" in _options(parser, command)["--seeds"].help, command


def test_the_episodes_seed_is_episode_seed_wherever_episodes_are_played(parser):
    having = [c for c in parser.subcommands if "--episode-seed" in _advertised(parser, c)]
    assert sorted(having) == ["check", "evaluate", "evaluate-dynamic"]
    for command in having:
        action = _options(parser, command)["--episode-seed"]
        assert action.default == 0 and "root of the episodes' seeds" in action.help


def test_workers_read_the_same_in_every_command(parser):
    having = [c for c in parser.subcommands if "--workers" in _advertised(parser, c)]
    assert sorted(having) == ["benchmark", "evaluate", "evaluate-dynamic", "submit", "train"]
    for command in having:
        action = _options(parser, command)["--workers"]
        assert action.help.startswith("N worker processes"), command
        assert action.default is None, command  # the default is decided where the work runs
        if command != "benchmark":
            assert "0: none, the work runs in this process" in action.help, command
        if command != "train":
            assert "default: the machine's cores" in action.help, command


@pytest.mark.parametrize("command", ["train", "evaluate", "evaluate-dynamic", "submit"])
@pytest.mark.parametrize("value", ["-1", "1025", "two"])
def test_a_bad_worker_count_is_the_same_one_line_everywhere(parser, capsys, command, value):
    argv = {
        "train": ["train", "--algo", "td3", "--task", "hopper"],
        "evaluate": ["evaluate", "p.npz"],
        "evaluate-dynamic": ["evaluate-dynamic", "run"],
        "submit": ["submit", "b", "p.npz", "--algo", "a", "--task", "hopper", "--seed", "0"],
    }[command]
    with pytest.raises(SystemExit):
        parser.parse_args([*argv, "--workers", value])
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1
    why = {
        "-1": "must be an integer >= 0, got -1",
        "1025": "must be at most 1024, got 1025",
        "two": "'two' is not an integer",
    }
    assert err == f"rrls {command}: error: argument --workers: {why[value]}"


def test_benchmark_refuses_zero_workers_saying_why(tmp_path, capsys):
    code = main(["benchmark", "--preset", "smoke", "--out", str(tmp_path / "b"), "--workers", "0"])
    assert code == 2
    err = capsys.readouterr().err.strip()
    assert err.splitlines() == [err] and "each benchmark run has its own process" in err


def test_evaluate_dynamic_defaults_to_every_core_like_evaluate(monkeypatch, capsys):
    import rrls.evaluation

    seen = {}

    class Result:
        env_id, mean, std = "x", 1.0, 0.0

    def fake(run_dir, **kwargs):
        seen.update(kwargs)
        return Result()

    monkeypatch.setattr(rrls.evaluation, "evaluate_run_dynamic", fake)
    assert main(["evaluate-dynamic", "run", "--episodes", "2"]) == 0
    assert seen["workers"] is None and seen["seed"] == 0  # None: the engine's, every core
    assert main(["evaluate-dynamic", "run", "--episode-seed", "7", "--workers", "0"]) == 0
    assert seen["workers"] == 0 and seen["seed"] == 7
    assert capsys.readouterr().err == ""


# -- the old spellings: one warning line, the same value -------------------------------------
@pytest.mark.parametrize(
    ("argv", "dest", "value", "old", "new"),
    [
        (["evaluate", "p.npz", "--seed", "3"], "episode_seed", 3, "--seed", "--episode-seed"),
        (["evaluate-dynamic", "r", "--seed", "4"], "episode_seed", 4, "--seed", "--episode-seed"),
        (["check", "--seed", "5"], "episode_seed", 5, "--seed", "--episode-seed"),
        (["benchmark", "--out", "b", "--jobs", "2"], "workers", 2, "--jobs", "--workers"),
        (
            ["train", "--algo", "td3", "--task", "hopper", "--env-workers", "2"],
            "env_workers",
            2,
            "--env-workers",
            "--workers",
        ),
    ],
)
def test_a_deprecated_spelling_still_parses_with_one_warning_line(
    parser, capsys, argv, dest, value, old, new
):
    args = parser.parse_args(argv)
    assert getattr(args, dest) == value
    assert capsys.readouterr().err == (
        f"rrls {argv[0]}: warning: {old} is deprecated; use {new} (same meaning)\n"
    )
    assert getattr(parser.parse_args([*argv[:-2], new, str(value)]), dest) == value
    assert capsys.readouterr().err == ""  # the new spelling: silent


def test_evaluate_with_the_old_seed_flag_gives_what_episode_seed_gives(tmp_path, capsys):
    from rrls.evaluation.policies import MLPPolicy

    MLPPolicy.random(4, 1, (8,), seed=0).save(tmp_path / "p.npz")  # the cwd (conftest)
    base = ["evaluate", "p.npz", "--task", "invertedpendulum", "--mesh", "2", "--episodes", "1"]
    base += ["--uncertainty", "1d", "--workers", "0"]
    assert main([*base, "--episode-seed", "9", "--out", "new"]) == 0
    new_out, _ = capsys.readouterr()
    assert main([*base, "--seed", "9", "--out", "old"]) == 0
    old_out, old_err = capsys.readouterr()
    assert old_err.splitlines()[0] == (
        "rrls evaluate: warning: --seed is deprecated; use --episode-seed (same meaning)"
    )
    assert "episode seed 9" in new_out
    assert old_out.replace("old", "new") == new_out  # the same table, episode seed included
