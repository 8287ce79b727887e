"""Outside probes of ``rrls submit`` (issue 26): every refusal is one line (exit 2) and changes
nothing; identity is the policy's actions; names and seeds are checked; concurrent submissions
lose no update and never silently replace each other."""

from __future__ import annotations

import json
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

from rrls.cli import main
from rrls.evaluation import BatchInvariant
from rrls.seeds import MAX_SEED
from rrls.submissions import steps as submission
from rrls.submissions.steps import SubmitError, create_benchmark, submit

pytest.importorskip("scipy")

POLICIES = """
    import numpy as np

    calls = 0


    def good(obs):
        return np.zeros((len(obs), 1))


    def flaky(obs):
        global calls
        calls += 1
        if calls > 3:  # the shape checks pass; an episode breaks it
            raise RuntimeError("policy broke mid-evaluation")
        return np.zeros((len(obs), 1))


    _gain = float(np.load(__file__.replace(".py", "_gain.npy")))


    def weighted(obs):  # a module whose weights live in another file
        return np.clip(_gain * obs[:, 1:2], -3.0, 3.0)
"""


def linear(*gains: float) -> BatchInvariant:
    k = np.asarray(gains, dtype=float)
    return BatchInvariant(lambda obs: np.clip((obs @ k)[:, None], -3.0, 3.0))


def zeros(obs: np.ndarray) -> np.ndarray:
    return np.zeros((len(obs), 1))


@pytest.fixture
def bench(tmp_path) -> Path:
    root = tmp_path / "bench"
    create_benchmark(root, "smoke", ("invertedpendulum",))
    return root


@pytest.fixture
def policies(tmp_path, monkeypatch):
    (tmp_path / "probepolicies.py").write_text(textwrap.dedent(POLICIES))
    np.save(tmp_path / "probepolicies_gain.npy", np.float64(1.0))
    monkeypatch.syspath_prepend(str(tmp_path))
    yield tmp_path
    sys.modules.pop("probepolicies", None)


def _snapshot(root: Path) -> dict[str, bytes]:
    return {str(p.relative_to(root)): p.read_bytes() for p in root.rglob("*") if p.is_file()}


def _submit(root: Path, policy: str, *args: str) -> int:
    base = ["submit", str(root), policy, "--task", "invertedpendulum", "--workers", "1"]
    return main([*base, *args] if "--seed" in args else [*base, "--seed", "0", *args])


def _one_line(capsys) -> str:
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "Traceback" not in err, err
    return err


def test_a_policy_raising_mid_evaluation_is_one_line_and_changes_nothing(bench, policies, capsys):
    before = _snapshot(bench)
    assert _submit(bench, "probepolicies:flaky", "--algo", "flaky") == 2
    assert "policy broke mid-evaluation" in _one_line(capsys)
    assert _snapshot(bench) == before  # no run, no staging left, benchmark.json as it was


def test_a_module_raising_on_import_is_one_line(bench, tmp_path, monkeypatch, capsys):
    (tmp_path / "probeboom.py").write_text("raise RuntimeError('import boom')\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    assert _submit(bench, "probeboom:policy", "--algo", "boom") == 2
    assert "RuntimeError: import boom" in _one_line(capsys)
    assert not (bench / "runs").exists()


@pytest.mark.parametrize("seed", ["9" * 40, "-1", str(2**32)])
def test_seeds_outside_what_the_store_keeps_are_refused(bench, policies, capsys, seed):
    assert _submit(bench, "probepolicies:good", "--algo", "big", "--seed", seed) == 2
    assert f"--seed: a seed is an integer from 0 to {MAX_SEED}" in _one_line(capsys)
    assert not (bench / "runs").exists()


def test_the_largest_seed_is_stored_and_reported(bench):
    done = submit(bench, "big", "invertedpendulum", MAX_SEED, zeros, workers=1)
    assert done.result["seed"] == MAX_SEED
    assert main(["report", str(bench), "--no-plots"]) == 0


def test_identity_is_the_actions_not_the_module_source(bench, policies, capsys):
    assert _submit(bench, "probepolicies:weighted", "--algo", "mine") == 0
    first = json.loads(next((bench / "runs").glob("mine-*/result.json")).read_text())
    sys.modules.pop("probepolicies", None)  # a new process: the module is imported again
    np.save(policies / "probepolicies_gain.npy", np.float64(-2.0))  # same source, new weights
    capsys.readouterr()
    assert _submit(bench, "probepolicies:weighted", "--algo", "mine") == 2
    assert "already submitted with another policy" in _one_line(capsys)
    sys.modules.pop("probepolicies", None)
    assert _submit(bench, "probepolicies:weighted", "--algo", "mine", "--overwrite") == 0
    again = json.loads(next((bench / "runs").glob("mine-*/result.json")).read_text())
    assert again["submitted"]["identity"] != first["submitted"]["identity"]
    assert again["submitted"]["identity"].startswith("actions:")
    sys.modules.pop("probepolicies", None)
    assert _submit(bench, "probepolicies:weighted", "--algo", "mine") == 0  # same: a no-op
    assert "already submitted (same policy" in capsys.readouterr().out


@pytest.mark.parametrize("name", ["sac", "SAC", "sacdr", "SAC-DR", "Td3", "NR-MDP", "paper"])
def test_every_built_in_name_is_reserved_in_any_case(bench, policies, capsys, name):
    assert _submit(bench, "probepolicies:good", "--algo", name) == 2
    assert f"--algo {name!r} is a built-in algorithm" in _one_line(capsys)


def test_installed_plug_in_names_are_reserved(bench, tmp_path, monkeypatch, capsys):
    info = tmp_path / "probe_algo-0.1.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: probe-algo\nVersion: 0.1\n")
    (info / "entry_points.txt").write_text("[rrls.algorithms]\nmyplug = probe_algo:Learner\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    with pytest.raises(SubmitError, match="'MyPlug' is an installed plug-in"):
        submit(bench, "MyPlug", "invertedpendulum", 0, zeros, workers=1)


def test_a_refused_submission_for_a_new_task_adds_no_task(bench, tmp_path, capsys):
    before = _snapshot(bench)
    with pytest.raises(SubmitError, match="'hopper' is not in the benchmark .* --add-task"):
        submit(bench, "mine", "hopper", 0, zeros, workers=1)  # not on purpose: refused
    assert _snapshot(bench) == before
    with pytest.raises(SubmitError, match="maps observations"):  # wrong shapes for hopper
        submit(bench, "mine", "hopper", 0, zeros, workers=1, add_task=True)
    assert _snapshot(bench) == before
    paper = tmp_path / "paper"
    create_benchmark(paper, "smoke", ("invertedpendulum",), physics="paper")
    before = _snapshot(paper)
    with pytest.raises(SubmitError, match="'swimmer' has no paper physics"):
        submit(paper, "mine", "swimmer", 0, zeros, workers=1, add_task=True)
    assert _snapshot(paper) == before


def test_a_benchmark_json_that_is_no_spec_and_unusable_paths_are_one_line(tmp_path, capsys):
    listed = tmp_path / "listed"
    listed.mkdir()
    (listed / "benchmark.json").write_text("[1, 2]\n")
    assert _submit(listed, "rrls.submissions:submit", "--algo", "x") == 2
    assert "benchmark.json is damaged (it holds a JSON list, not an object)" in _one_line(capsys)
    long = tmp_path / ("x" * 300)
    assert _submit(long, "rrls.submissions:submit", "--algo", "x", "--preset", "smoke") == 2
    assert "File name too long" in _one_line(capsys)


def _during_evaluation(monkeypatch, action) -> None:
    """Run ``action`` once, while the next submission evaluates (another command at work)."""
    original = submission.run_evaluation
    pending = [action]

    def evaluate_then_act(*args, **kwargs):
        result = original(*args, **kwargs)
        while pending:
            pending.pop()()
        return result

    monkeypatch.setattr(submission, "run_evaluation", evaluate_then_act)


def test_concurrent_submissions_adding_tasks_lose_no_update(bench, monkeypatch):
    _during_evaluation(
        monkeypatch,
        lambda: submit(bench, "b", "inverteddoublependulum", 0, zeros, workers=1, add_task=True),
    )
    act = lambda obs: np.zeros((len(obs), 2))  # noqa: E731
    submit(bench, "a", "reacher", 0, act, workers=1, add_task=True)
    tasks = json.loads((bench / "benchmark.json").read_text())["tasks"]
    assert set(tasks) == {"invertedpendulum", "inverteddoublependulum", "reacher"}
    runs = sorted(p.name for p in (bench / "runs").iterdir())
    assert runs == ["a-reacher-1d-seed0", "b-inverteddoublependulum-1d-seed0"]


def test_the_same_name_at_once_with_two_policies_is_refused_once(bench, monkeypatch):
    _during_evaluation(
        monkeypatch, lambda: submit(bench, "mine", "invertedpendulum", 0, zeros, workers=1)
    )
    with pytest.raises(SubmitError, match="already submitted with another policy"):
        submit(bench, "mine", "invertedpendulum", 0, linear(1.0, 0, 0, 0), workers=1)
    result = json.loads(next((bench / "runs").glob("mine-*/result.json")).read_text())
    assert result["submitted"]["source"].endswith("zeros")  # the first one stayed
    staging = bench / "submissions" / ".staging"
    assert not staging.exists() or not list(staging.iterdir())  # nothing staged is left


def test_withdraw_takes_a_submission_out_and_later_reports_stay_complete(bench, capsys):
    from rrls.cli import main

    act = lambda obs: np.zeros((len(obs), 2))  # noqa: E731
    submit(bench, "mine", "invertedpendulum", 0, zeros, workers=1)
    submit(bench, "other", "reacher", 0, act, workers=1, add_task=True)
    assert "reacher" in json.loads((bench / "benchmark.json").read_text())["tasks"]
    assert main(["withdraw", str(bench), "--algo", "other"]) == 0
    assert "withdrawn: other-reacher-1d-seed0" in capsys.readouterr().out
    # the task only it had leaves the submissions-only benchmark: no missing cells later
    assert json.loads((bench / "benchmark.json").read_text())["tasks"] == ["invertedpendulum"]
    assert sorted(p.name for p in (bench / "runs").iterdir()) == ["mine-invertedpendulum-1d-seed0"]
    assert main(["withdraw", str(bench), "--algo", "other"]) == 2
    assert "no submission of other" in capsys.readouterr().err
