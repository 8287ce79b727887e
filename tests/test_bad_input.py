"""Bad input and faults: one line naming the culprit, nothing changed, CLI exit status 2."""

from __future__ import annotations

import json
import os
import pathlib
import signal
import stat
import subprocess
import sys
import textwrap
import threading
import time
import warnings

import gymnasium as gym
import numpy as np
import pytest

import rrls  # noqa: F401
from rrls.argtypes import nonnegative_int, positive_float, positive_int
from rrls.cli import main
from rrls.envs import HopperParamsBound, RobustHopper
from rrls.evaluation import MLPPolicy, PolicyError, evaluate
from rrls.uncertainty import UncertaintySet
from rrls.wrappers import DomainRandomization, DynamicAdversarial, ProbabilisticActionRobust

ROOT = pathlib.Path(__file__).resolve().parents[1]


def _ip_policy(**metadata) -> MLPPolicy:
    policy = MLPPolicy.random(4, 1, (8,), seed=0)
    policy.metadata.update(metadata)
    return policy


@pytest.fixture
def files(tmp_path):
    """A policy without metadata, a run directory, an empty directory, junk files."""
    _ip_policy().save(tmp_path / "bare.npz")
    _ip_policy(task="invertedpendulum", uncertainty="2d", algorithm="td3", seed=4).save(
        tmp_path / "run" / "policy.npz"
    )
    (tmp_path / "empty").mkdir()
    (tmp_path / "text.txt").write_text("not a policy\n")
    (tmp_path / "text.npz").write_text("not a policy\n")
    return tmp_path


def _run(argv: list[str], capsys) -> tuple[int, str]:
    """Exit status and stderr of ``rrls ARGV`` (argparse's own errors exit through SystemExit)."""
    try:
        code = main(argv)
    except SystemExit as stop:
        code = stop.code
    err = capsys.readouterr().err
    assert "Traceback" not in err
    return code, err


# -- CLI ----------------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("argv", "culprit"),
    [
        (["check", "--steps", "-5"], "--steps"),
        (["check", "--steps", "x"], "--steps"),
        (["check", "--seed", "-1"], "--seed"),
        (["check", "--task", "nosuch"], "--task"),
        (["evaluate", "{d}/bare.npz", "--task", "nosuch"], "--task"),
        (["evaluate", "{d}/bare.npz", "--uncertainty", "9d"], "--uncertainty"),
        (["evaluate", "{d}/bare.npz", "--mesh", "0"], "--mesh"),
        (["evaluate", "{d}/bare.npz", "--episodes", "0"], "--episodes"),
        (["evaluate", "{d}/bare.npz", "--workers", "-1"], "--workers"),  # 0: in this process
        (["evaluate", "{d}/bare.npz", "--batch-size", "-2"], "--batch-size"),
        (["evaluate", "{d}/bare.npz", "--seed", "-1"], "--seed"),
    ],
)
def test_cli_refuses_bad_options_naming_them(argv, culprit, files, capsys):
    code, err = _run([a.format(d=files) for a in argv], capsys)
    assert code == 2
    assert err.strip().splitlines()[-1].startswith(f"rrls {argv[0]}: error: argument {culprit}")


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["evaluate", "{d}/missing.npz", "--task", "hopper"], "no policy file {d}/missing.npz"),
        (["evaluate", "{d}/empty", "--task", "hopper"], "{d}/empty holds no policy.npz"),
        (["evaluate", "{d}/text.txt", "--task", "hopper"], "{d}/text.txt: unknown policy file"),
        (["evaluate", "{d}/text.npz", "--task", "hopper"], "{d}/text.npz is not an rrls MLP"),
        (["evaluate", "{d}/run", "--task", "hopper"], "trained on 'invertedpendulum'"),
        (["evaluate", "{d}/bare.npz"], "--task is required"),
        (
            ["evaluate", "{d}/bare.npz", "--task", "invertedpendulum", "--uncertainty", "3d"],
            "task 'invertedpendulum' has no uncertainty set '3d'; valid: 1d, 2d, rarl, nominal",
        ),
        (
            ["evaluate", "{d}/bare.npz", "--task", "invertedpendulum", "--split", "shell"],
            "split 'shell': the kind must be one of interpolation, extrapolation",
        ),
        (["plot", "{d}/nosuchdir"], "no evaluation directory {d}/nosuchdir"),
        (["plot", "{d}/empty"], "{d}/empty holds no summary.json"),
    ],
)
def test_cli_usage_errors_are_one_line_and_exit_2(argv, message, files, capsys):
    code, err = _run([a.format(d=files) for a in argv], capsys)
    assert code == 2
    assert err.count("\n") == 1 and err.startswith(f"rrls {argv[0]}: ")
    assert message.format(d=files) in err
    assert "pickle" not in err  # an unknown file is never offered to unpickling


def test_cli_from_a_shell_prints_no_traceback(tmp_path):
    out = subprocess.run(
        [sys.executable, "-m", "rrls", "evaluate", str(tmp_path / "nope.npz"), "--task", "hopper"],
        capture_output=True,
        text=True,
        cwd=ROOT,
    )
    assert out.returncode == 2
    assert out.stderr == f"rrls evaluate: error: no policy file {tmp_path / 'nope.npz'}\n"


def test_argparse_type_helpers():
    assert positive_int("3") == 3 and nonnegative_int("0") == 0 and positive_float("1e-3") == 1e-3
    for helper, bad in [
        (positive_int, "0"),
        (positive_int, "1.5"),
        (nonnegative_int, "-1"),
        (positive_float, "0"),
        (positive_float, "nan"),
        (positive_float, "inf"),
        (positive_float, "x"),
    ]:
        with pytest.raises(Exception, match="must be|not"):  # argparse.ArgumentTypeError
            helper(bad)


def test_evaluate_a_run_directory_uses_its_set_and_records_the_policy(files, capsys):
    out = files / "ev"
    assert main(["evaluate", str(files / "run"), "--mesh", "2", "--episodes", "1",
                 "--workers", "1", "--out", str(out)]) == 0  # fmt: skip
    summary = json.loads((out / "summary.json").read_text())
    assert summary["uncertainty_name"] == "2d" and summary["points"] == 4
    assert summary["policy_algorithm"] == "td3" and summary["policy_seed"] == 4
    assert summary["policy_run_dir"] == str(files / "run")
    assert "invertedpendulum / 2d" in capsys.readouterr().out


# -- evaluation faults --------------------------------------------------------------------
def test_an_evaluation_directory_is_locked_while_in_use(tmp_path):
    from rrls.files import DirectoryLock

    out = tmp_path / "ev"
    held, release = threading.Event(), threading.Event()

    def hold() -> None:  # another holder (a thread here; another process the same)
        with DirectoryLock(out):
            held.set()
            release.wait(30)

    holder = threading.Thread(target=hold)
    holder.start()
    held.wait(30)
    try:
        with pytest.raises(FileExistsError, match=f"{out} is in use"):
            evaluate(_ip_policy(), "invertedpendulum", "1d", mesh=2, episodes=1, out_dir=out)
        assert not (out / "evaluation.json").exists() and not (out / "chunks").exists()
    finally:
        release.set()
        holder.join()
    # released: the same evaluation now runs
    evaluate(_ip_policy(), "invertedpendulum", "1d", mesh=2, episodes=1, out_dir=out)
    assert (out / "summary.json").exists()


@pytest.mark.parametrize("damage", [b"", b"PK\x03\x04 truncated", b"garbage", "wrong-shape"])
def test_a_damaged_chunk_is_named_and_recomputed(tmp_path, damage):
    from rrls.evaluation.chunks import CHUNK

    kwargs = dict(mesh=3, episodes=40, workers=1, out_dir=tmp_path / "ev")
    first = evaluate(_ip_policy(), "invertedpendulum", "1d", **kwargs)
    chunk = tmp_path / "ev" / "chunks" / "000001.npz"
    assert chunk.exists() and CHUNK < 120
    if damage == "wrong-shape":
        np.savez(chunk, **{k: np.zeros(3) for k in ("return", "length", "terminated", "diverged")})
    else:
        chunk.write_bytes(damage)
    (tmp_path / "ev" / "summary.json").unlink()
    with pytest.warns(UserWarning, match=f"chunk file {chunk} is unreadable.*recomputing"):
        again = evaluate(_ip_policy(), "invertedpendulum", "1d", **kwargs)
    assert again.episodes.equals(first.episodes)
    assert np.load(chunk)["return"].shape == (CHUNK,)


def test_files_respect_the_umask(tmp_path):
    from rrls.files import atomic_write_json

    previous = os.umask(0o002)
    try:
        path = atomic_write_json(tmp_path / "a.json", {"x": 1})
        assert stat.S_IMODE(path.stat().st_mode) == 0o664
        os.umask(0o077)
        path = atomic_write_json(tmp_path / "b.json", {"x": 1})
        assert stat.S_IMODE(path.stat().st_mode) == 0o600
    finally:
        os.umask(previous)


@pytest.mark.e2e
def test_workers_exit_with_their_killed_parent(tmp_path):
    """kill -9 of an evaluation must not leave its workers alive, blocked on a queue."""
    script = tmp_path / "slow.py"
    script.write_text(
        textwrap.dedent(
            f"""
            import os, pathlib, time
            import numpy as np
            from rrls.evaluation import evaluate

            marks = pathlib.Path({str(tmp_path)!r})

            def slow(obs):
                (marks / f"worker-{{os.getpid()}}").touch()
                time.sleep(0.05)  # the whole evaluation would take > 20 s
                return np.zeros((len(obs), 1))

            evaluate(slow, "invertedpendulum", "1d", mesh=10, episodes=300, workers=2)
            """
        )
    )
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), *sys.path])}
    proc = subprocess.Popen([sys.executable, str(script)], cwd=ROOT, env=env)
    deadline = time.monotonic() + 60
    workers: set[int] = set()
    while len(workers) < 2 and time.monotonic() < deadline:
        workers = {int(p.name.split("-")[1]) for p in tmp_path.glob("worker-*")} - {proc.pid}
        time.sleep(0.05)
    assert len(workers) == 2, "the workers never started"
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    deadline = time.monotonic() + 8
    while time.monotonic() < deadline and any(_alive(pid) for pid in workers):
        time.sleep(0.05)
    alive = [pid for pid in workers if _alive(pid)]
    for pid in alive:  # clean up before failing
        os.kill(pid, signal.SIGKILL)
    assert not alive, f"workers {alive} outlived their parent"


def _alive(pid: int) -> bool:
    try:
        state = pathlib.Path(f"/proc/{pid}/stat").read_text().split(")")[-1].split()[0]
    except (FileNotFoundError, ProcessLookupError):
        return False
    return state != "Z"  # a zombie has exited; only its parent's reaper is missing


def test_a_policy_returning_non_numbers_is_a_policy_error():
    with pytest.raises(PolicyError, match="actions must be real numbers"):
        evaluate(lambda o: np.full((len(o), 1), "up"), "invertedpendulum", "1d", mesh=2)


def test_evaluate_refuses_bad_counts_naming_them():
    for name, value in [("episodes", 0), ("mesh", -1), ("workers", -1), ("batch_size", 0)]:
        with pytest.raises(ValueError, match=f"{name} must be an integer >= 1, got {value}"):
            evaluate(_ip_policy(), "invertedpendulum", "1d", **{name: value})


# -- envs and wrappers --------------------------------------------------------------------
@pytest.mark.parametrize(
    "params", [{"worldfriction": 1e300}, {"worldfriction": 1e7}, {"torsomass": 1e12}]
)
def test_values_that_overflow_mujoco_are_refused_and_change_nothing(params):
    env = RobustHopper()
    before = env.get_params()
    name = next(iter(params))
    with pytest.raises(ValueError, match=f"{name} must be <="):
        env.set_params(**params)
    assert env.get_params() == before
    with pytest.raises(ValueError, match=name):
        RobustHopper(**params)


@pytest.mark.parametrize(
    "bounds",
    [{"torsomass": (-1.0, 2.0)}, {"worldfriction": (-1.0, 1.0)}, {"thighmass": (0.0, 1.0)}],
)
@pytest.mark.parametrize("wrapper", [DomainRandomization, DynamicAdversarial])
def test_unphysical_boxes_are_refused_when_the_wrapper_is_built(bounds, wrapper):
    name = next(iter(bounds))
    with pytest.raises(ValueError, match=f"uncertainty set bound out of range: {name}"):
        wrapper(RobustHopper(), bounds)


@pytest.mark.parametrize("alpha", ["x", None, float("nan"), -0.1, 1.5, True, [0.1]])
def test_alpha_is_named_when_refused(alpha):
    with pytest.raises(ValueError, match="alpha must be a number in \\[0, 1\\]"):
        ProbabilisticActionRobust(RobustHopper(), alpha=alpha)


def test_a_refused_reset_does_not_consume_a_random_draw():
    def episodes(refuse: bool) -> list[dict[str, float]]:
        env = DomainRandomization(RobustHopper(), HopperParamsBound.TWO_DIM.value)
        draws = [env.reset(seed=1)[1]["randomized_params"]]
        if refuse:
            for bad in ({"torsomas": 1.0}, {"torsomass": -1.0}, "not a dict"):
                with pytest.raises(ValueError):
                    env.reset(options=bad)
            with pytest.raises(ValueError):
                env.reset(seed=5, options={"thighmass": float("nan")})
        draws += [env.reset()[1]["randomized_params"] for _ in range(2)]
        return draws

    assert episodes(refuse=True) == episodes(refuse=False)


def test_registered_ids_refuse_bad_params_with_nothing_changed():
    env = gym.make("rrls/robust-hopper-domain-randomization-3d-v0")
    env.reset(seed=0)
    before = env.get_params()
    with pytest.raises(ValueError, match="footmass is a mass"):
        env.set_params(torsomass=2.0, footmass=-3.0)
    assert env.get_params() == before


def test_uncertainty_sets_refuse_malformed_bounds():
    for bad in [{"torsomass": "ab"}, {"torsomass": (1.0,)}, {"torsomass": ("a", "b")}, [1, 2]]:
        with pytest.raises((ValueError, TypeError), match="bounds"):
            UncertaintySet.from_bounds(bad)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert UncertaintySet((), [], []).mesh(4).shape == (1, 0)


def test_damaged_result_files_are_named(tmp_path, capsys):
    out = tmp_path / "ev"
    evaluate(_ip_policy(), "invertedpendulum", "1d", mesh=2, episodes=1, out_dir=out)
    (out / "summary.json").write_text("{ truncated")
    code, err = _run(["plot", str(out)], capsys)
    assert code == 2 and f"{out / 'summary.json'} is damaged" in err
    (out / "summary.json.sha256").unlink()  # an unsealed (older) file: still checked as JSON
    code, err = _run(["plot", str(out)], capsys)
    assert code == 2 and f"{out / 'summary.json'} is damaged (not valid JSON" in err
    (out / "evaluation.json").write_text("[]")
    with pytest.raises(ValueError, match="evaluation.json is damaged .*JSON list, not an object"):
        evaluate(_ip_policy(), "invertedpendulum", "1d", mesh=2, episodes=1, out_dir=out)


def test_library_entry_points_refuse_bad_sets_and_seeds_before_building_anything():
    from rrls import generate_evaluation_set

    built = []

    def factory(**params):
        built.append(params)
        return RobustHopper(**params)

    factory.param_specs = RobustHopper.param_specs
    with pytest.raises(ValueError, match="torsomass is a mass"):
        generate_evaluation_set(factory, {"torsomass": [-1.0, 2.0]})
    assert not built
    with pytest.raises(ValueError, match=r"seed must be an integer in \[0, 2\*\*32\), got -1"):
        evaluate(_ip_policy(), "invertedpendulum", "1d", seed=-1)


def test_a_policy_of_another_task_is_named_whatever_its_form(files):
    run = files / "run"  # trained on invertedpendulum
    for policy in (run, str(run / "policy.npz"), MLPPolicy.load(run / "policy.npz")):
        with pytest.raises(ValueError, match="trained on 'invertedpendulum', not on task 'hopper'"):
            evaluate(policy, "hopper", "1d", mesh=2, episodes=1)


def test_dynamic_evaluation_names_the_policy_that_returns_non_numbers():
    from rrls.evaluation import evaluate_dynamic

    still = lambda o: np.zeros((len(o), 1))  # noqa: E731
    words = lambda o: np.full((len(o), 2), "push")  # noqa: E731
    with pytest.raises(PolicyError, match="the adversary returned <U4 values"):
        evaluate_dynamic(still, words, "invertedpendulum", "adversarial", "rarl", episodes=1)
    with pytest.raises(
        PolicyError, match="the protagonist returned actions of shape \\(1,\\) for 1"
    ):
        evaluate_dynamic(lambda o: np.zeros(1), still, "invertedpendulum", "nr", episodes=1)


def test_cli_evaluate_split_prints_in_and_out_of_distribution(files, capsys):
    # a run that trained under a split is evaluated with it by default (its metadata says so)
    policy = _ip_policy(task="invertedpendulum", uncertainty="1d", split="extrapolation:0.5")
    policy.save(files / "split" / "policy.npz")
    argv = ["evaluate", str(files / "split"), "--mesh", "3", "--episodes", "1", "--workers", "1"]
    assert main([*argv, "--out", str(files / "ev")]) == 0
    out = capsys.readouterr().out
    assert "in distribution (extrapolation:0.5)" in out and "over 1 points" in out
    assert "out of distribution" in out and "over 2 points" in out
    assert main([*argv, "--out", str(files / "ev2"), "--split", "interpolation:0.5"]) == 0
    assert "in distribution (interpolation:0.5)" in capsys.readouterr().out
