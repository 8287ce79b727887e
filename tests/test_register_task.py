"""rrls.register_task: a task declared in user code works everywhere a built-in one does
(make, sets, resolve, evaluate, search, wrappers, train, benchmark through an entry point), and
bad declarations are refused at registration with the valid names listed."""

from __future__ import annotations

import importlib.util
import json
import pickle
import runpy
import sys
import textwrap
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import rrls
from rrls import registry
from rrls.cli import main
from rrls.envs import FORCE_ENVS, ROBUST_ENVS, get_uncertainty_set, resolve
from rrls.evaluation import evaluate, search_worst_case
from rrls.params import Parameter, body_id, joint_params, mass_params
from rrls.registry import TASKS, validate_task
from rrls.wrappers import DomainRandomization

REPO = Path(__file__).resolve().parents[1]
needs_torch = pytest.mark.skipif(
    importlib.util.find_spec("torch") is None, reason="training needs torch (rrls[train])"
)

# a user's declaration, at module level as in a user's package
TASK = rrls.register_task(
    "usertask",
    "InvertedDoublePendulum-v5",
    name="UserTask",
    params=mass_params({"cart": "cart", "pole": "pole", "pole2": "pole2"})
    + joint_params({"hinge": "hinge"}, kinds=("damping",)),
    sets={
        "1d": {"polemass": (1.0, 10.0)},
        "2d": {"polemass": (1.0, 10.0), "pole2mass": (1.0, 10.0)},
        "rarl": {"poleforce_x": (-3.0, 3.0)},
    },
    planar=True,
)


def _policy(obs: np.ndarray) -> np.ndarray:
    return np.clip(3 * obs[:, 1:2] + 6 * obs[:, 2:3] + 0.6 * obs[:, 6:7], -1, 1)


def test_registered_task_makes_every_id_with_nominal_values_from_the_model():
    env = gym.make("rrls/robust-usertask-v0")
    model = env.unwrapped.model
    params = env.get_params(kinds="all")
    assert params["pole2mass"] == model.body_mass[body_id(model, "pole2")]
    assert params["hingedamping"] == 0.05  # the XML's value, read, not declared
    assert type(env.unwrapped) is ROBUST_ENVS["usertask"]
    assert type(env.unwrapped).__name__ == "RobustUserTask"
    assert env.spec.max_episode_steps == gym.spec("InvertedDoublePendulum-v5").max_episode_steps
    force = gym.make("rrls/force-usertask-v0")
    assert type(force.unwrapped) is FORCE_ENVS["usertask"]
    assert {"poleforce_x", "poleforce_y", "cartforce_x"} <= set(force.get_params())
    for env_id in (
        "rrls/robust-usertask-adversarial-2d-v0",
        "rrls/robust-usertask-domain-randomization-2d-v0",
        "rrls/robust-usertask-adversarial-forces-v0",
        "rrls/probabilistic-action-robust-usertask-v0",
    ):
        e = gym.make(env_id)
        e.reset(seed=0)
        e.step(e.action_space.sample())
    # at nominal parameters, bit-identical to the plain Gymnasium env
    plain, robust = gym.make("InvertedDoublePendulum-v5"), gym.make("rrls/robust-usertask-v0")
    o1, _ = plain.reset(seed=3)
    o2, _ = robust.reset(seed=3)
    for _ in range(20):
        a = np.array([0.3])
        np.testing.assert_array_equal(o1, o2)
        o1, *_ = plain.step(a)
        o2, *_ = robust.step(a)


def test_registered_task_pickles_and_changes_physics():
    env = rrls.envs.RobustUserTask(pole2mass=8.0)
    twin = pickle.loads(pickle.dumps(env))
    assert twin.get_params()["pole2mass"] == 8.0
    assert type(twin) is type(env)
    a, b = rrls.envs.RobustUserTask(), rrls.envs.RobustUserTask(pole2mass=8.0)
    a.reset(seed=0), b.reset(seed=0)
    for _ in range(10):
        oa, *_ = a.step(np.array([0.5]))
        ob, *_ = b.step(np.array([0.5]))
    assert not np.array_equal(oa, ob)


def test_sets_resolve_and_wrappers_work():
    box = get_uncertainty_set("usertask", "2d")
    assert box.names == ("polemass", "pole2mass") and box.family == "robust"
    assert box.nominal[1] == pytest.approx(4.19873858)
    assert resolve("usertask", "rarl").family == "force"
    assert resolve("USERTASK", "nominal").box.dim == 0
    env = DomainRandomization(gym.make("rrls/robust-usertask-v0"), box)
    _, info = env.reset(seed=0)
    assert 1.0 <= info["polemass"] <= 10.0


def test_evaluate_rows_equal_the_plain_gymnasium_loop_and_search_runs():
    result = evaluate(_policy, "usertask", "2d", mesh=2, episodes=1, workers=1)
    frame = result.episodes
    assert len(frame) == 4
    for _, row in frame.iterrows():
        env = gym.make("rrls/robust-usertask-v0")
        env.set_params(polemass=row["polemass"], pole2mass=row["pole2mass"])
        obs, _ = env.reset(seed=int(row["seed"]))
        total, done = 0.0, False
        while not done:
            obs, r, term, trunc, _ = env.step(_policy(obs[None])[0])
            total += r
            done = term or trunc
        assert total == row["return"]
    found = search_worst_case(_policy, "usertask", "2d", budget=4, workers=1)
    assert 1.0 <= found.params["polemass"] <= 10.0


@pytest.mark.parametrize(
    "kwargs, needle",
    [
        (
            dict(params=mass_params({"torso": "nobody"})),
            "no body named 'nobody' in the model; valid bodies: world, torso, thigh, leg, foot",
        ),
        (
            dict(params=(Parameter("kneedamping", "dof_damping", "knee"),)),
            "valid joints: rootx, rootz, rooty, thigh_joint, leg_joint, foot_joint",
        ),
        (
            dict(params=(Parameter("kneegear", "actuator_gear", "knee"),)),
            "valid: thigh_joint, leg_joint, foot_joint",
        ),
        (
            dict(params=mass_params({"torso": "torso"}), sets={"1d": {"thighmass": (1, 2)}}),
            "set '1d' names unknown parameter(s) ['thighmass']",
        ),
        (
            dict(params=mass_params({"torso": "torso"}), sets={"1d": {"torsomass": (-1, 2)}}),
            "torsomass is a mass and must be > 0, got -1.0",
        ),
        (
            dict(params=(Parameter("g", "opt_timestep"),), sets={"1d": {"g": (0.001, 5.0)}}),
            "g must be <= 0.1 (timestep)",
        ),
        (dict(params=mass_params({"torso": "torso"}) * 2), "duplicate parameter names"),
    ],
)
def test_bad_declarations_are_refused_listing_valid_names(kwargs, needle):
    before = dict(TASKS), set(gym.registry)
    with pytest.raises(ValueError) as err:
        rrls.register_task("badtask", "Hopper-v5", name="BadTask", **kwargs)
    assert needle in str(err.value)
    assert len(str(err.value).splitlines()) == 1
    assert (dict(TASKS), set(gym.registry)) == before  # nothing registered


def test_bad_keys_envs_and_duplicates_are_refused():
    with pytest.raises(ValueError, match="lower-case letters and digits"):
        rrls.register_task("Bad-Key", "Hopper-v5")
    with pytest.raises(ValueError, match="no Gymnasium env 'Nope-v5'"):
        rrls.register_task("nope", "Nope-v5")
    with pytest.raises(ValueError, match="already registered"):
        rrls.register_task("hopper", "Hopper-v5", params=mass_params({"torso": "torso"}))
    with pytest.raises(ValueError, match="class name stem 'Hopper' is used by task 'hopper'"):
        rrls.register_task("hopper2", "Hopper-v5")
    # the same declaration again is a no-op (a module imported twice)
    again = rrls.register_task(
        "usertask",
        "InvertedDoublePendulum-v5",
        name="UserTask",
        params=TASK.params,
        sets=TASK.sets,
        planar=True,
    )
    assert again is TASK


def test_replace_rebuilds_classes_and_ids():
    spec = dict(name="ReplaceMe", params=mass_params({"torso": "torso"}))
    rrls.register_task("replaceme", "Hopper-v5", **spec)
    first = ROBUST_ENVS["replaceme"]
    rrls.register_task(
        "replaceme", "Hopper-v5", replace=True, **{**spec, "sets": {"1d": {"torsomass": (1, 2)}}}
    )
    assert ROBUST_ENVS["replaceme"] is not first
    from rrls import envs

    assert envs.RobustReplaceMe is ROBUST_ENVS["replaceme"]  # the module follows the table
    assert pickle.loads(pickle.dumps(envs.RobustReplaceMe)) is envs.RobustReplaceMe
    assert envs.ReplaceMeParamsBound.ONE_DIM.value == {"torsomass": [1, 2]}
    gym.make("rrls/robust-replaceme-domain-randomization-1d-v0").reset(seed=0)
    registry.unregister_task("replaceme")
    assert "rrls/robust-replaceme-v0" not in gym.registry and "replaceme" not in TASKS
    assert not hasattr(envs, "RobustReplaceMe")


def test_the_built_in_env_classes_are_class_statements():
    import inspect

    from rrls import envs
    from rrls.envs.classes import BUILT_IN
    from rrls.envs.paper import paper_specs

    assert len(BUILT_IN) == 2 * len(registry.BUILTIN_TASKS) + 2 * 6  # + the paper's six twins
    for (key, kind, paper), cls in BUILT_IN.items():
        assert inspect.getsource(cls).splitlines()[1].startswith(f"class {cls.__name__}(")
        assert getattr(envs, cls.__name__) is cls and cls.task is TASKS[key]
        task = TASKS[key]
        declared = task.params if kind == "robust" else task.forces
        assert cls.paper is paper
        assert cls.param_specs == (paper_specs(task, kind) if paper else declared)


def test_built_in_tables_match_the_compiled_models():
    for key in ("ant", "halfcheetah", "hopper", "humanoidstandup", "invertedpendulum", "walker"):
        validate_task(TASKS[key])  # every row's body / geom / joint / actuator exists


def test_cli_accepts_a_registered_task(capsys):
    assert main(["check", "--task", "usertask", "--steps", "3"]) == 0
    assert "usertask" in capsys.readouterr().out


@needs_torch
def test_train_on_a_registered_task(tmp_path):
    out = tmp_path / "run"
    args = ["train", "--algo", "dr", "--task", "usertask", "--uncertainty", "2d"]
    args += ["--steps", "200", "--learning-starts", "50", "--eval-every", "100"]
    args += ["--hidden", "8", "8", "--batch-size", "16", "--out", str(out)]
    assert main(args) == 0
    meta = json.loads((out / "run.json").read_text())
    assert meta["task"] == "usertask" and meta["obs_dim"] == 9


PLUGIN = """
import rrls
from rrls.params import mass_params


def register():
    rrls.register_task(
        "plugintask",
        "InvertedPendulum-v5",
        name="PluginTask",
        params=mass_params({"pole": "pole", "cart": "cart"}),
        sets={"1d": {"polemass": (1.0, 20.0)}},
        planar=True,
    )
"""


@pytest.fixture
def plugin(tmp_path, monkeypatch):
    """An installed-looking package declaring a task through the ``rrls.tasks`` entry point."""
    (tmp_path / "rrls_plugin_demo.py").write_text(textwrap.dedent(PLUGIN))
    info = tmp_path / "rrls_plugin_demo-0.1.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: rrls-plugin-demo\nVersion: 0.1\n")
    (info / "entry_points.txt").write_text("[rrls.tasks]\nplugintask = rrls_plugin_demo:register\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setattr(registry, "_plugins_loaded", False)
    yield tmp_path
    if "plugintask" in TASKS:
        registry.unregister_task("plugintask")
    sys.modules.pop("rrls_plugin_demo", None)


def test_entry_point_task_is_found_by_name(plugin):
    assert "plugintask" not in TASKS
    assert rrls.tasks.get_task("plugintask").name == "PluginTask"  # loads the entry points


@pytest.mark.e2e
@needs_torch
def test_benchmark_on_an_entry_point_task(plugin, tmp_path, capsys):
    out = tmp_path / "bench"
    args = ["benchmark", "--preset", "smoke", "--workers", "1", "--out", str(out)]
    assert main([*args, "--algos", "td3", "--tasks", "plugintask"]) == 0
    summary = json.loads((out / "report" / "summary.json").read_text())
    assert summary["tasks"] == ["plugintask"]


def test_tutorial_add_a_task_runs(capsys, monkeypatch):
    monkeypatch.setattr(sys, "argv", ["add_a_task.py", "--smoke"])
    runpy.run_path(str(REPO / "docs" / "tutorials" / "add_a_task.py"), run_name="__main__")
    out = capsys.readouterr().out
    assert "2d set: worst" in out and "search: worst" in out


def test_centre_of_mass_rows_on_simple_bodies_are_refused_at_registration():
    with pytest.raises(ValueError, match="'object' is compiled as 'simple'.*bodies that can: "):
        rrls.register_task(
            "badpusher",
            "Pusher-v5",
            name="BadPusher",
            params=(Parameter("objectcom_x", "body_ipos", "object"),),
        )
    assert "badpusher" not in TASKS


@needs_torch
def test_train_takes_any_set_the_task_declares_and_the_tasks_time_limit(tmp_path, capsys):
    rrls.register_task(
        "namedsets",
        "InvertedPendulum-v5",
        name="NamedSets",
        params=mass_params({"pole": "pole", "cart": "cart"}),
        # (a force set too: tests/test_registration expects every task's adversarial-forces id)
        sets={"heavypole": {"polemass": (5.0, 20.0)}, "rarl": {"poleforce_x": (-1.0, 1.0)}},
        planar=True,
        max_episode_steps=40,
    )
    out = tmp_path / "run"
    args = ["train", "--algo", "dr", "--task", "namedsets", "--steps", "60"]
    args += ["--learning-starts", "50", "--eval-every", "0", "--hidden", "8", "--batch-size", "8"]
    assert main([*args, "--uncertainty", "heavypole", "--out", str(out)]) == 0
    config = json.loads((out / "run.json").read_text())["config"]
    assert config["uncertainty"] == "heavypole" and config["max_episode_steps"] == 40
    capsys.readouterr()  # the first run's progress lines
    assert main([*args, "--uncertainty", "3d", "--out", str(tmp_path / "x")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.endswith("task 'namedsets' has no uncertainty set '3d'; valid: heavypole, rarl")
    assert len(err.splitlines()) == 1


def test_display_names_come_from_the_registry():
    from rrls.report.names import task_name

    assert task_name("usertask") == "UserTask" and task_name("reacher") == "Reacher"
    assert task_name("walker") == "Walker"  # the paper's heading
    assert task_name("not-a-task") == "not-a-task"
