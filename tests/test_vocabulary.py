"""One vocabulary across commands: ``--seeds``, ``--workers``, ``--physics`` labels, ``--yes``,
and help texts that describe, give defaults and list choices."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

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
    from rrls.benchmark.grid import Benchmark, make_spec
    from rrls.report.reference import load_reference

    stored = make_spec("smoke").flat_json()  # as benchmark.json held it before the protocol
    assert stored["physics"] == "v5"
    assert Benchmark.from_json({**stored, "physics": "rrls-v5"}) == make_spec("smoke")
    with pytest.raises(ValueError, match="physics 'paper-v4' is the paper's physics on Gym"):
        Benchmark.from_json({**stored, "physics": "paper-v4"})  # ran v4: not read as today's paper
    shipped = json.loads((ROOT / "rrls" / "report" / "quick_reference.json").read_text())
    assert shipped["physics"] == "rrls-v5"  # the file as shipped, untouched
    assert load_reference("quick").physics == "v5"
    for old in ROOT.glob("docs/results/*/benchmark.json"):
        assert Benchmark.from_json(json.loads(old.read_text())).physics == "v5", old


# -- --seeds: one grammar -------------------------------------------------------------------
SMOKE = ["benchmark", "--preset", "smoke", "--algos", "td3", "--dry-run"]


def _dry_seeds(capsys, tmp_path: Path, *seeds: str) -> tuple[list[int], str]:
    pytest.importorskip("torch")
    assert main([*SMOKE, "--out", str(tmp_path / "b"), "--seeds", *seeds]) == 0
    out, err = capsys.readouterr()
    runs = [line.split("-seed")[-1] for line in out.splitlines() if "-seed" in line]
    assert not (tmp_path / "b").exists()
    return sorted(map(int, runs)), err


def test_benchmark_seeds_take_a_list_or_a_range(tmp_path, capsys):
    assert _dry_seeds(capsys, tmp_path, "0-2") == ([0, 1, 2], "")
    assert _dry_seeds(capsys, tmp_path, "0,3,5") == ([0, 3, 5], "")
    assert _dry_seeds(capsys, tmp_path, "4-5,9") == ([4, 5, 9], "")


def test_benchmark_seeds_count_form_is_retired_with_what_to_write(tmp_path, capsys):
    assert main(["benchmark", "--preset", "smoke", "--out", str(tmp_path), "--seeds", "3"]) == 2
    assert capsys.readouterr().err.strip() == (
        "rrls benchmark: error: --seeds 3: a bare number is no longer a count of seeds here (it "
        "is one seed in every command); write --seeds 0-2 for 3 seeds from 0, or --seeds 3-3 for "
        "seed 3 alone"
    )


@pytest.mark.parametrize(
    ("seeds", "needle"),
    [("0", "write --seeds 0-0 for seed 0 alone"), ("a", "'a' is not a seed"), ("2-1", "empty")],
)
def test_bad_benchmark_seeds_are_one_line(tmp_path, capsys, seeds, needle):
    assert main(["benchmark", "--preset", "smoke", "--out", str(tmp_path), "--seeds", seeds]) == 2
    err = capsys.readouterr().err
    assert needle in err and len(err.strip().splitlines()) == 1


def test_train_seeds_are_the_same_grammar():
    pytest.importorskip("torch")
    from rrls.cli.train_options import configs_from_args

    parser = build_parser(with_train=True)
    base = ["train", "--algo", "td3", "--task", "hopper"]
    for text, want in (("0-2", [0, 1, 2]), ("0,3,5", [0, 3, 5]), ("3", [3])):
        configs, _ = configs_from_args(parser.parse_args([*base, "--seeds", text]))
        assert [c.seed for c in configs] == want


def test_quickstart_takes_seeds_and_its_old_first_seed_flag_warns(capsys):
    from rrls.cli.quickstart_command import quickstart_seeds

    parser = build_parser(with_train=False)
    assert quickstart_seeds(parser.parse_args(["quickstart", "--seeds", "4-6"])) == [4, 5, 6]
    assert quickstart_seeds(parser.parse_args(["quickstart"])) is None  # the preset's 0-2
    assert capsys.readouterr().err == ""
    assert quickstart_seeds(parser.parse_args(["quickstart", "--seed", "1"])) == [1, 2, 3]
    assert "--seed 1 is deprecated; write --seeds 1-3" in capsys.readouterr().err


# -- --workers: one name for worker processes -------------------------------------------
def _options(command: str) -> dict[str, str]:
    parser = build_parser(with_train=True)
    return {
        flag: action.help
        for action in parser.subcommands[command]._actions
        for flag in action.option_strings
    }


@pytest.mark.parametrize("command", ["evaluate", "submit", "benchmark", "train"])
def test_every_command_with_worker_processes_calls_them_workers(command):
    if command == "train":
        pytest.importorskip("torch")
    options = _options(command)
    assert "processes" in options["--workers"]
    assert not {"--jobs", "--env-workers"} & {
        f for f, h in options.items() if h != "==SUPPRESS=="
    }  # the old spellings are hidden


def test_old_worker_flags_still_work_with_a_notice(tmp_path, capsys):
    pytest.importorskip("torch")
    assert main([*SMOKE, "--out", str(tmp_path / "b"), "--jobs", "3"]) == 0
    out, err = capsys.readouterr()
    assert "3 workers" in out
    assert (
        err.strip() == "rrls benchmark: warning: --jobs is deprecated; use --workers (same meaning)"
    )
    parser = build_parser(with_train=True)
    base = ["train", "--algo", "td3", "--task", "hopper"]
    assert parser.parse_args([*base, "--workers", "2"]).env_workers == 2
    assert parser.parse_args([*base]).env_workers is None
    assert parser.parse_args([*base, "--env-workers", "1"]).env_workers == 1
    assert (
        "rrls train: warning: --env-workers is deprecated; use --workers" in capsys.readouterr().err
    )


# -- help: descriptions, defaults, choices ----------------------------------------------
def test_every_subcommand_describes_itself_and_every_option():
    pytest.importorskip("torch")
    parser = build_parser(with_train=True)
    for name, sub in parser.subcommands.items():
        assert sub.description and len(sub.description) > 40, name
        for action in sub._actions:
            if action.option_strings and action.help != "==SUPPRESS==":
                assert action.help, f"rrls {name} {action.option_strings[0]} has no help"
        text = sub.format_help()
        for action in sub._actions:
            for choice in action.choices or ():
                if name != "train" or action.dest != "task":  # train lists tasks in usage
                    assert str(choice) in text, (name, action.dest, choice)


def test_help_gives_defaults_and_choices_where_they_exist():
    benchmark = build_parser(with_train=False).subcommands["benchmark"].format_help()
    presets = "{smoke,quick,hopper-200k,hopper,halfcheetah,paper}"
    for needle in ("{local,ray}", "default: local", presets, "default: paper"):
        assert needle in benchmark
    assert "random steps before learning" in benchmark  # --learning-starts
    submit = build_parser(with_train=False).subcommands["submit"].format_help()
    assert "{adversarial,nr,pr}" in submit
    check = build_parser(with_train=False).subcommands["check"].format_help()
    assert "(default: 100)" in check and "(default: 0)" in check


def test_top_level_help_lists_every_built_in_algorithm():
    pytest.importorskip("torch")
    from rrls.agents import ALGOS  # the algorithm table the learners are registered in

    text = build_parser(with_train=False).format_help()
    for algo in ALGOS:
        assert f"{algo}," in text or f"{algo})" in text, algo
    assert "sac," in text and "sacdr)" in text


# -- --yes: a large grid from a terminal asks first --------------------------------------
class _Terminal:
    def isatty(self) -> bool:
        return True


def test_a_large_grid_asks_from_a_terminal_and_nothing_starts_on_no(tmp_path, monkeypatch, capsys):
    pytest.importorskip("torch")
    monkeypatch.delenv("CI", raising=False)
    monkeypatch.setattr("sys.stdin", _Terminal())
    asked = []
    monkeypatch.setattr("builtins.input", lambda prompt: asked.append(prompt) or "n")
    out = tmp_path / "bench"
    assert main(["benchmark", "--out", str(out)]) == 1  # the paper preset: 250 runs
    assert asked == ["rrls benchmark: start 250 runs (see --dry-run for the estimate)? [y/N] "]
    assert "nothing started (--yes starts without asking)" in capsys.readouterr().err
    assert not out.exists()


def test_confirmation_never_blocks_a_script_or_ci(monkeypatch):
    from rrls.cli.benchmark_options import CONFIRM_ABOVE, confirmed

    def refuse(prompt: str) -> str:
        raise AssertionError("asked")

    monkeypatch.setattr("builtins.input", refuse)
    monkeypatch.delenv("CI", raising=False)
    monkeypatch.setattr("sys.stdin", _Terminal())
    assert confirmed("benchmark", 500, yes=True)  # --yes
    assert confirmed("benchmark", CONFIRM_ABOVE, yes=False)  # small: no question
    monkeypatch.setenv("CI", "true")
    assert confirmed("benchmark", 500, yes=False)  # CI
    monkeypatch.delenv("CI")
    monkeypatch.setattr("sys.stdin", open(__file__))  # not a terminal
    assert confirmed("benchmark", 500, yes=False)
    monkeypatch.setattr("sys.stdin", _Terminal())
    monkeypatch.setattr("builtins.input", lambda prompt: "y")
    assert confirmed("benchmark", 500, yes=False)
