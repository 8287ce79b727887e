"""Bad input and faults: one line naming the culprit, nothing changed, CLI exit status 2."""

from __future__ import annotations

import pathlib
import random
import subprocess
import sys

import gymnasium as gym
import numpy as np
import pytest
from conftest import TASK_KEYS

import rrls
from rrls.envs import (
    FORCE_ENVS,
    ROBUST_ENVS,
    HopperParamsBound,
    RobustHopper,
    nominal_params,
    resolve,
)
from rrls.tasks import TASKS
from rrls.uncertainty import UncertaintySet

ROOT = pathlib.Path(__file__).resolve().parents[1]


# -- the resolver -----------------------------------------------------------------------
@pytest.mark.parametrize("task", TASK_KEYS)
def test_every_named_set_resolves_to_its_family_class_and_box(task):
    for name in TASKS[task].sets:
        r = resolve(task, name)
        assert r.family == TASKS[task].families[name] == r.box.family
        assert r.env_class is (FORCE_ENVS if r.family == "force" else ROBUST_ENVS)[task]
        params = r.make_env().get_params()
        assert set(r.box.names) <= set(params)  # the box names the family's parameters
        assert r.box.nominal.tolist() == [params[n] for n in r.box.names]
    assert resolve(task, "rarl").family == "force"
    nominal = resolve(task, "nominal")
    assert nominal.box.dim == 0 and nominal.is_nominal and nominal.env_class is ROBUST_ENVS[task]


def test_user_boxes_take_their_family_from_the_parameter_table():
    forces = resolve("hopper", UncertaintySet(("footforce_x",), [-1.0], [1.0]))
    assert forces.family == "force" and forces.name is None
    assert forces.box.nominal.tolist() == [0.0]  # filled in from the model
    masses = resolve("walker2d", UncertaintySet(("torsomass",), [1.0], [2.0]))
    assert masses.family == "robust" and masses.task == "walker"
    with pytest.raises(ValueError, match="not all of one family.*force parameters: torsoforce"):
        resolve("hopper", UncertaintySet(("torsomass", "footforce_x"), [1, 0], [2, 1]))
    with pytest.raises(ValueError, match="valid: 1d, 2d, 3d, rarl, nominal"):
        resolve("hopper", "9d")
    with pytest.raises(ValueError, match="valid tasks: ant, halfcheetah"):
        resolve("cartpole", "1d")
    with pytest.raises(ValueError, match="torsomass is a mass"):
        resolve("hopper", UncertaintySet(("torsomass",), [-1.0], [2.0]))


def test_the_set_to_env_rule_lives_only_in_the_task_table():
    """No module of the evaluation/env stack re-derives a family from a set or parameter name."""
    mine = [
        *sorted((ROOT / "rrls" / "evaluation").glob("*.py")),
        *sorted((ROOT / "rrls" / "wrappers").glob("*.py")),
        ROOT / "rrls" / "check.py",
        ROOT / "rrls" / "_registration.py",
        ROOT / "rrls" / "envs" / "__init__.py",
    ]
    for path in mine:
        text = path.read_text()
        for pattern in ('== "rarl"', '"force_" in', "'force_' in", 'if name == "rarl"'):
            assert pattern not in text, f"{path.name} contains {pattern}"


def test_search_worst_case_takes_a_user_built_set():
    from rrls.evaluation import MLPPolicy, search_worst_case

    policy = MLPPolicy.random(4, 1, (8,), seed=1)
    box = UncertaintySet(("polemass",), [1.0], [31.0])  # no nominal, no family given
    found = search_worst_case(policy, "invertedpendulum", box, budget=8, popsize=4, workers=1)
    assert box.contains([found.params["polemass"]])
    assert found.value == found.trace["mean_return"].min()


def test_nominal_everywhere_is_the_model_as_shipped():
    """evaluation_points / default_evaluation_set / evaluate with "nominal" keep Hopper's foot
    friction at 2.0 (setting worldfriction=1.0 would overwrite it)."""
    from rrls.evaluation import (
        MLPPolicy,
        default_evaluation_set,
        evaluate,
        evaluation_points,
    )

    assert evaluation_points("hopper", "nominal").shape == (1, 0)
    envs = default_evaluation_set("hopper", "nominal")
    assert len(envs) == 1
    shipped = gym.make("Hopper-v5").unwrapped.model.geom_friction
    np.testing.assert_array_equal(envs[0].model.geom_friction, shipped)
    assert shipped[:, 0].max() == 2.0
    policy = MLPPolicy.random(11, 3, (8,), seed=0)
    result = evaluate(policy, "hopper", "nominal", episodes=2, workers=1, max_episode_steps=30)
    assert len(result.episodes) == 2 and result.uncertainty is None


# -- no hidden shared state -------------------------------------------------------------
def test_nominal_params_cannot_be_changed_by_a_caller():
    first = nominal_params("hopper")
    first["torsomass"] = 99.0
    first.clear()
    assert nominal_params("hopper")["torsomass"] != 99.0
    assert resolve("hopper", "1d").box.nominal.tolist() == [
        nominal_params("hopper")["worldfriction"]
    ]


def test_evaluation_leaves_no_cached_envs_behind():
    from rrls.evaluation import MLPPolicy, engine, evaluate, lanes

    evaluate(MLPPolicy.random(4, 1, (8,)), "invertedpendulum", "1d", mesh=2, episodes=1)
    assert lanes._cache() == {}
    assert not hasattr(engine, "_WORKER") and not hasattr(engine, "spec_for")
    assert "env_kwargs" not in lanes.Rollouts.__dataclass_fields__


def test_fast_stepper_only_for_the_exact_default_classes():
    from rrls.evaluation.kernels import FastStepper, GenericStepper, make_stepper

    class Custom(RobustHopper):
        def step(self, action):  # a subclass may change anything
            obs, reward, *rest = super().step(action)
            return obs, 2 * reward, *rest

    assert type(make_stepper([RobustHopper(torsomass=2.0)], "hopper")) is FastStepper
    assert type(make_stepper([Custom()], "hopper")) is GenericStepper
    assert type(make_stepper([RobustHopper(forward_reward_weight=3.0)], "hopper")) is GenericStepper
    assert type(make_stepper([RobustHopper()], "walker")) is GenericStepper
    assert type(make_stepper([ROBUST_ENVS["ant"]()], "ant")) is GenericStepper


@pytest.mark.parametrize("task", ["hopper", "walker", "halfcheetah", "invertedpendulum"])
@pytest.mark.parametrize("family", ["robust", "force"])
def test_fast_and_generic_steppers_agree_step_by_step(task, family):
    """Observation, reward, termination and divergence, every step, bit for bit."""
    from rrls.evaluation.kernels import FastStepper, GenericStepper

    cls = (FORCE_ENVS if family == "force" else ROBUST_ENVS)[task]
    lanes = 3
    fast_envs, generic_envs = [cls() for _ in range(lanes)], [cls() for _ in range(lanes)]
    if family == "force":
        name = next(n for n in cls().get_params() if n.endswith("force_x"))
        for env in (*fast_envs, *generic_envs):
            env.set_params(**{name: 2.0})
    fast, generic = FastStepper(fast_envs, task), GenericStepper(generic_envs)
    rng = np.random.default_rng(7)
    space = fast_envs[0].action_space
    every = np.arange(lanes)
    episode = [0] * lanes

    def start(lane: int) -> None:
        seed = 100 * lane + episode[lane]
        a, _ = fast_envs[lane].reset(seed=seed)
        b, _ = generic_envs[lane].reset(seed=seed)
        np.testing.assert_array_equal(a, b)
        fast.reset(lane, a)
        generic.reset(lane, b)

    for lane in range(lanes):
        start(lane)
    for step in range(150):
        actions = rng.uniform(space.low, space.high, (lanes, space.shape[0])).astype(space.dtype)
        got = fast.step(every, actions)
        want = generic.step(every, actions)
        for what, g, w in zip(("obs", "reward", "terminated", "diverged"), got, want):
            np.testing.assert_array_equal(g, w, err_msg=f"{what} differs at step {step}")
        for lane in np.flatnonzero(want[2] | want[3]):
            episode[lane] += 1
            start(int(lane))


# -- code written for the original RRLS -------------------------------------------------
def test_original_module_paths_import():
    with pytest.warns(DeprecationWarning):  # the legacy names still import, and say so
        from rrls._interface import ModifiedParamsEnv, check_protocol_modified_params_env
    from rrls.envs.ant import AntParamsBound, RobustAnt  # noqa: F401
    from rrls.envs.half_cheetah import HalfCheetahParamsBound, RobustHalfCheetah  # noqa: F401
    from rrls.envs.hopper import ForceHopper, HopperParamsBound  # noqa: F401
    from rrls.envs.humanoid import HumanoidStandupParamsBound, RobustHumanoidStandUp  # noqa: F401
    from rrls.envs.pendulum import InvertedPendulumParamsBound  # noqa: F401
    from rrls.envs.walker import RobustWalker2d, Walker2dParamsBound  # noqa: F401

    with pytest.warns(DeprecationWarning):
        from rrls.evaluate import EVALUATION_ROBUST_HOPPER_1D, generate_evaluation_set  # noqa: F401
        from rrls.wrappers import ProbalisticActionRobust
        from rrls.wrappers.probalistic_action_robust import ProbalisticActionRobust as Misspelt
    from rrls.wrappers.probabilistic_action_robust import ProbabilisticActionRobust

    assert ProbalisticActionRobust is ProbabilisticActionRobust is Misspelt

    env = rrls.make_wrapped_env(
        RobustHopper,
        rrls.wrappers.DomainRandomization,
        params_bound=HopperParamsBound.ONE_DIM.value,
    )
    assert isinstance(env.unwrapped, RobustHopper)
    assert check_protocol_modified_params_env(RobustAnt())
    assert isinstance(RobustAnt(), ModifiedParamsEnv)
    assert len(EVALUATION_ROBUST_HOPPER_1D) == 10
    assert EVALUATION_ROBUST_HOPPER_1D[0].unwrapped.__class__ is RobustHopper


def test_evaluation_constants_are_built_on_first_access_only():
    code = (
        "import rrls.envs, rrls.evaluate as ev\n"
        "built = []\n"
        "orig = rrls.envs.RobustAnt.__init__\n"
        "rrls.envs.RobustAnt.__init__ = lambda s, **k: (built.append(1), orig(s, **k))[1]\n"
        "assert not any(n.startswith('EVALUATION_') for n in vars(ev)), 'built at import'\n"
        "from rrls.evaluate import EVALUATION_ROBUST_ANT_3D as s\n"
        "assert len(s) == 1000 and not built, built\n"
        "s[5]; assert len(built) == 1\n"
        "assert 'EVALUATION_ROBUST_INVERTED_PENDULUM_2D' in ev.__all__\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT)
    assert out.returncode == 0, out.stderr


def test_evaluation_set_is_a_lazy_list():
    from rrls import generate_evaluation_set

    built = []

    def factory(**params):
        built.append(params)
        return RobustHopper(**params)

    a = generate_evaluation_set(factory, HopperParamsBound.TWO_DIM.value, 3)
    b = generate_evaluation_set(factory, HopperParamsBound.ONE_DIM.value, 2)
    both = a + b
    assert len(both) == 11 and not built  # concatenation builds nothing
    assert [e.get_params()["worldfriction"] for e in both[9:]] == [0.1, 3.0]
    assert len(built) == 2
    assert len([None] + a) == 10 and len(a + [None]) == 10
    order = a.points.tolist()
    random.Random(0).shuffle(a)
    shuffled = [[e.get_params()["worldfriction"], e.get_params()["torsomass"]] for e in a]
    assert sorted(shuffled) == sorted(order) and shuffled != order


def test_dynamic_adversarial_uses_the_original_arithmetic():
    """The original test's check: parameters == low + ((a + 1) * (high - low)) / 2 in float32."""
    for env_id in ("rrls/robust-hopper-adversarial-3d-v0", "rrls/robust-ant-adversarial-forces-v0"):
        env = gym.make(env_id)
        env.action_space.seed(3)
        bounds = env.get_wrapper_attr("params_bound")
        env.reset(seed=0)
        for _ in range(20):
            agent, nature = env.action_space.sample()
            env.step((agent, nature))
            expected = {
                k: lo + ((v - (-1)) * (hi - lo)) / 2
                for (k, (lo, hi)), v in zip(bounds.items(), nature)
            }
            assert env.get_params() == expected  # exact, as the original's users compare
            assert set(env.unwrapped.get_params()) > set(expected)  # all of them stay readable


def test_probabilistic_action_robust_info_has_the_original_keys():
    env = gym.make("rrls/probabilistic-action-robust-hopper-v0")
    env.reset(seed=0)
    agent, adversary = np.ones(3, np.float32), -np.ones(3, np.float32)
    *_, info = env.step((agent, adversary))
    np.testing.assert_array_equal(info["agent action"], agent)
    np.testing.assert_array_equal(info["adversarial action"], adversary)
    np.testing.assert_allclose(info["executed_action"], 0.8 * np.ones(3), rtol=1e-6)


def test_an_evaluation_in_another_thread_keeps_its_envs():
    """Each thread has its own env cache: one evaluation ending does not close another's."""
    import threading

    import numpy as np

    from rrls.evaluation import MLPPolicy, evaluate, lanes

    spec = lanes.Rollouts("invertedpendulum", "robust", (), np.zeros((1, 0)), np.zeros((1, 1)))
    mine = lanes.make_rollout_envs(spec, 2)
    other = threading.Thread(
        target=lambda: evaluate(
            MLPPolicy.random(4, 1, (8,)), "invertedpendulum", "1d", mesh=2, episodes=1, workers=1
        )
    )
    other.start()
    other.join(120)
    assert lanes.make_rollout_envs(spec, 2) == mine  # this thread's envs, not rebuilt
    mine[0].reset(seed=0)  # and not closed
    lanes.clear_env_cache()
    assert lanes._cache() == {}
