"""The public Python API: ``rrls.evaluate`` callable, ``__all__`` everywhere, legacy names that
warn, ``set_params`` through any wrapper, ``mesh=`` with ``nb_mesh_dim=`` as a deprecated alias."""

from __future__ import annotations

import importlib
import inspect
import pkgutil
import subprocess
import sys
import warnings
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import rrls

ROOT = Path(__file__).resolve().parents[1]


def _still(obs: np.ndarray) -> np.ndarray:
    return np.zeros((len(obs), 1))


KW = dict(mesh=2, episodes=1, workers=1, max_episode_steps=20)


# -- rrls.evaluate: the original module path; calling it is deprecated --------------------
def test_calling_the_module_rrls_evaluate_warns_and_evaluates():
    from rrls import evaluate
    from rrls.evaluation import evaluate as function

    want = function(_still, "invertedpendulum", "1d", **KW)
    with pytest.warns(DeprecationWarning, match="use rrls.evaluation.evaluate"):
        got = evaluate(_still, "invertedpendulum", "1d", **KW)
    assert got.worst_case == want.worst_case and len(got.per_point) == 2
    with pytest.warns(DeprecationWarning):
        assert rrls.evaluate(_still, "invertedpendulum", "1d", **KW).average_case == (
            want.average_case
        )
    assert inspect.signature(evaluate) == inspect.signature(function)  # what help/IDEs show
    assert rrls.evaluate.evaluate is function


@pytest.mark.e2e
def test_the_evaluation_function_in_a_fresh_interpreter_warns_nothing():
    code = (
        "import numpy as np, rrls, rrls.evaluation\n"
        "r = rrls.evaluation.evaluate(lambda o: np.zeros((len(o), 1)), 'invertedpendulum', '1d',"
        " mesh=2, episodes=1, workers=1, max_episode_steps=5)\n"
        "assert len(r.per_point) == 2\n"
        "from rrls.evaluate import generate_evaluation_set\n"
    )
    out = subprocess.run(
        [sys.executable, "-W", "error::DeprecationWarning", "-c", code],
        capture_output=True,
        text=True,
        cwd=ROOT,
    )
    assert out.returncode == 0, out.stderr


def test_original_constants_still_import_with_a_deprecation_warning():
    with pytest.warns(DeprecationWarning, match=r"default_evaluation_set\(\"hopper\", \"1d\"\)"):
        from rrls.evaluate import EVALUATION_ROBUST_HOPPER_1D
    assert len(EVALUATION_ROBUST_HOPPER_1D) == 10
    with pytest.warns(DeprecationWarning):  # every access warns, not only the first
        import rrls.evaluate as module

        assert module.EVALUATION_ROBUST_HOPPER_1D is EVALUATION_ROBUST_HOPPER_1D
    with pytest.raises(AttributeError, match="EVALUATION_ROBUST_NOPE"):
        module.EVALUATION_ROBUST_NOPE  # noqa: B018


@pytest.mark.parametrize(
    ("module", "name", "new"),
    [
        ("rrls._interface", "ModifiedParamsEnv", "ModifiedParamsEnv"),
        ("rrls._interface", "ModifiedParams", "ModifiedParamsEnv"),
        ("rrls._interface", "check_protocol_modified_params_env", "is_modified_params_env"),
        ("rrls.wrappers.probalistic_action_robust", "ProbalisticActionRobust", None),
        ("rrls.wrappers.probabilistic_action_robust", "ProbalisticActionRobust", None),
        ("rrls.wrappers", "ProbalistActionRobustWrapper", None),
        ("rrls.wrappers", "ProbalisticActionRobust", None),
    ],
)
def test_legacy_names_work_and_warn(module: str, name: str, new: str | None):
    mod = importlib.import_module(module)
    with pytest.warns(DeprecationWarning, match=name) as caught:
        value = getattr(mod, name)
    assert caught[0].filename == __file__  # the warning points at the caller's line
    if new is None:
        from rrls.wrappers.action_robust import ProbabilisticActionRobust as new_value
    else:
        new_value = getattr(importlib.import_module("rrls.interface"), new)
    assert value is new_value


@pytest.mark.parametrize(
    ("module", "old", "new"),
    [
        ("rrls.params", "ParamSpec", "Parameter"),
        ("rrls.evaluation.lanes", "RolloutSpec", "Rollouts"),
        ("rrls.benchmark.grid", "Spec", "Benchmark"),
    ],
)
def test_renamed_classes_keep_their_old_names_with_a_warning(module: str, old: str, new: str):
    mod = importlib.import_module(module)
    with pytest.warns(DeprecationWarning, match=f"{old} is deprecated; use {module}.{new}"):
        value = getattr(mod, old)
    assert value is getattr(mod, new) and old not in mod.__all__ and new in mod.__all__
    with pytest.raises(AttributeError, match="no attribute 'NoSuchName'"):
        mod.NoSuchName  # noqa: B018 - the module's own AttributeError stays


def test_rrls_exports_parameter_and_keeps_paramspec_out_of_all_and_dir():
    import warnings

    import rrls
    from rrls.params import Parameter

    assert rrls.Parameter is Parameter and "Parameter" in rrls.__all__
    assert "Parameter" in dir(rrls) and "ParamSpec" not in rrls.__all__
    with warnings.catch_warnings():
        # reading every name dir() lists (as pytest's fixture scan does) warns of nothing
        warnings.simplefilter("error", DeprecationWarning)
        for name in dir(rrls):
            getattr(rrls, name)
        warnings.simplefilter("ignore", DeprecationWarning)
        assert rrls.ParamSpec is Parameter  # old code still runs


def test_check_protocol_still_checks():
    from rrls.envs import RobustAnt
    from rrls.interface import is_modified_params_env

    assert is_modified_params_env(RobustAnt()) and not is_modified_params_env(object())


# -- __all__ in every public module -----------------------------------------------------
#: implementation modules reached through their package (``rrls.agents``, ``rrls.benchmark``,
#: ``rrls.submissions``, ``rrls.report``; ``rrls.experiments`` is their deprecated former home)
#: and the command-line entry points: not part of the importable API
PRIVATE_PACKAGES = (
    "rrls.agents.",
    "rrls.benchmark.",
    "rrls.submissions.",
    "rrls.report.",
    "rrls.experiments.",
)
ENTRY_POINTS = {"rrls.cli", "rrls.check", "rrls.__main__"}


def public_modules() -> list[str]:
    names = ["rrls"]
    for info in pkgutil.walk_packages(rrls.__path__, "rrls."):
        parts = info.name.split(".")
        if any(p.startswith("_") for p in parts) or info.name in ENTRY_POINTS:
            continue
        if info.name.startswith(PRIVATE_PACKAGES):
            continue
        names.append(info.name)
    return [*names, "rrls._interface"]  # the original package's module path


def test_the_walk_finds_the_api_modules():
    names = public_modules()
    for expected in ("rrls.envs", "rrls.wrappers.schedules", "rrls.evaluation.mesh", "rrls.agents"):
        assert expected in names


@pytest.mark.parametrize("name", public_modules())
def test_every_public_module_has_a_resolving_all_without_duplicates(name: str):
    try:
        module = importlib.import_module(name)
    except ImportError as err:  # an optional dependency (torch, pettingzoo) is not installed
        pytest.skip(f"{name}: {err}")
    assert hasattr(module, "__all__"), f"{name} has no __all__"
    names = list(module.__all__)
    assert len(names) == len(set(names)), f"{name}.__all__ repeats a name"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)  # legacy names resolve, and warn
        missing = [n for n in names if not hasattr(module, n)]
    assert not missing, f"{name}.__all__ names what it lacks: {missing}"


# -- set_params through any wrapper -----------------------------------------------------
def test_set_params_through_a_gymnasium_wrapper():
    env = gym.wrappers.RecordEpisodeStatistics(gym.make("rrls/robust-hopper-v0"))
    assert not hasattr(env, "set_params")  # what a user meets: Gymnasium does not forward it
    env.get_wrapper_attr("set_params")(torsomass=2.5)  # the documented Gymnasium way
    assert env.unwrapped.get_params()["torsomass"] == 2.5
    rrls.set_params(env, torsomass=1.5)  # rrls's helper, the same through any stack
    assert rrls.get_params(env)["torsomass"] == 1.5
    with pytest.raises(ValueError, match="nosuchparam"):
        rrls.set_params(env, nosuchparam=1.0)


def test_set_params_on_an_env_without_it_is_one_line():
    env = gym.wrappers.RecordEpisodeStatistics(gym.make("CartPole-v1"))
    with pytest.raises(TypeError, match="no set_params anywhere in its wrapper stack"):
        rrls.set_params(env, x=1.0)


# -- mesh= in Python as on the command line ---------------------------------------------
def test_mesh_keyword_and_its_deprecated_alias():
    from rrls.envs import HopperParamsBound, RobustHopper
    from rrls.evaluation import default_evaluation_set, evaluate, evaluation_points
    from rrls.evaluation import generate_evaluation_set as generate

    new = evaluate(_still, "invertedpendulum", "1d", **KW)
    old_kw = {**KW, "nb_mesh_dim": KW["mesh"]}
    del old_kw["mesh"]
    with pytest.warns(DeprecationWarning, match=r"nb_mesh_dim=\.\.\.\) is deprecated; use mesh="):
        old = evaluate(_still, "invertedpendulum", "1d", **old_kw)
    assert old.worst_case == new.worst_case and len(old.per_point) == 2
    with pytest.raises(TypeError, match="both nb_mesh_dim= .* and mesh="):
        evaluate(_still, "invertedpendulum", "1d", mesh=2, nb_mesh_dim=3)
    with pytest.warns(DeprecationWarning):
        assert evaluation_points("hopper", "2d", nb_mesh_dim=3).shape == (9, 2)
    assert evaluation_points("hopper", "2d", mesh=3).shape == (9, 2)
    with pytest.warns(DeprecationWarning):
        assert len(default_evaluation_set("hopper", "1d", nb_mesh_dim=4)) == 4
    bounds = HopperParamsBound.ONE_DIM.value
    assert len(generate(RobustHopper, bounds, 3)) == 3  # the original positional call: silent
    with pytest.warns(DeprecationWarning):
        assert len(generate(RobustHopper, bounds, nb_mesh_dim=3)) == 3


MOVED = [
    ("rrls.twin.tasks", "rrls.twin.catalog", "TWIN_TASKS"),
    ("rrls.twin.check", "rrls.twin.agreement", "divergence"),
    *((f"rrls.agents.{a}", f"rrls.agents.algos.{a}", "Learner") for a in ("td3", "dr", "sacdr")),
    ("rrls.experiments.spec", "rrls.benchmark.grid", "Benchmark"),
    ("rrls.experiments.runner", "rrls.benchmark.runner", "benchmark"),
    ("rrls.experiments.submission", "rrls.submissions.steps", "submit"),
    ("rrls.experiments.report", "rrls.report.writer", "make_report"),
    ("rrls.experiments.stats", "rrls.report.stats", "t_interval"),
]


def test_every_former_experiments_module_has_a_new_home():
    """``rrls.experiments`` was split into benchmark / submissions / report: each of its 34
    former modules still imports under its old path (``MOVED`` there), and nothing else is left
    in it but that table."""
    from rrls.experiments import MOVED as SPLIT

    assert len(SPLIT) == 34
    for new in SPLIT.values():
        assert importlib.util.find_spec(new) is not None, new
    assert {new.split(".")[1] for new in SPLIT.values()} == {"benchmark", "submissions", "report"}
    folder = Path(importlib.import_module("rrls.experiments").__file__).parent
    assert sorted(p.name for p in folder.iterdir() if p.name != "__pycache__") == ["__init__.py"]


def test_the_old_experiments_submit_still_submits_with_a_warning():
    import rrls.experiments
    from rrls.submissions import submit

    with pytest.warns(DeprecationWarning, match="use rrls.submissions.submit"):
        assert rrls.experiments.submit is submit


@pytest.mark.parametrize(("old", "new", "name"), MOVED)
def test_moved_modules_import_under_their_old_names_with_a_warning(old, new, name):
    """No file is left at a moved module's old path; importing it gives the new module."""
    import sys

    sys.modules.pop(old, None)
    with pytest.warns(DeprecationWarning, match=f"{old} is deprecated; use {new}"):
        module = importlib.import_module(old)
    assert module is importlib.import_module(new) and hasattr(module, name)
    package, _, leaf = old.rpartition(".")
    sys.modules.pop(old, None)
    parent = importlib.import_module(package)
    if leaf in vars(parent):  # the import above set it; read it again as a fresh process would
        delattr(parent, leaf)
    with pytest.warns(DeprecationWarning, match=f"{old} is deprecated"):
        exec(f"from {package} import {leaf} as found", {})  # the old spelling
    assert not (Path(importlib.import_module(package).__file__).parent / f"{leaf}.py").exists()
