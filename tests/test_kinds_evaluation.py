"""Every parameter kind is meshable in evaluate and search_worst_case, and the fast stepper stays
bit-identical to each env's own step with lanes of different kinds (timestep included)."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

from rrls.envs import ROBUST_ENVS
from rrls.evaluation import evaluate, search_worst_case
from rrls.evaluation.kernels import FastStepper, GenericStepper, make_stepper
from rrls.uncertainty import UncertaintySet


def _lane_params(cls) -> list[dict[str, float]]:
    """Three lanes, each with other kinds changed."""
    first = {}
    for spec in cls.param_specs:
        first.setdefault(spec.field, spec.name)
    nominal = cls().get_params(kinds="all")
    return [
        {"timestep": nominal["timestep"] * 1.3, "gravity": 7.0},
        {first["dof_damping"]: 3.0, first["actuator_gear"]: nominal[first["actuator_gear"]] * 0.6},
        {
            first["body_ipos"]: 0.03,
            first["body_friction"]: 0.5,
            first["dof_armature"]: 0.2,
            first["dof_frictionloss"]: 0.5,
        },
    ]


@pytest.mark.parametrize("task", ["hopper", "walker", "halfcheetah", "invertedpendulum"])
def test_fast_stepper_is_exact_for_every_kind(task):
    cls = ROBUST_ENVS[task]
    lanes = _lane_params(cls)
    fast_envs = [cls(**p) for p in lanes]
    generic_envs = [cls(**p) for p in lanes]
    fast = make_stepper(fast_envs, task)
    assert type(fast) is FastStepper
    generic = GenericStepper(generic_envs)
    every = np.arange(len(lanes))
    for lane in every:
        a, _ = fast_envs[lane].reset(seed=int(lane))
        b, _ = generic_envs[lane].reset(seed=int(lane))
        np.testing.assert_array_equal(a, b)
        fast.reset(int(lane), a)
        generic.reset(int(lane), b)
    rng = np.random.default_rng(3)
    space = fast_envs[0].action_space
    alive = np.ones(len(lanes), dtype=bool)
    for step in range(100):
        actions = rng.uniform(space.low, space.high, (len(lanes), space.shape[0]))
        live = np.flatnonzero(alive)
        got, want = fast.step(live, actions[live]), generic.step(live, actions[live])
        for what, g, w in zip(("obs", "reward", "terminated", "diverged"), got, want):
            np.testing.assert_array_equal(g, w, err_msg=f"{what} differs at step {step}")
        alive[live[want[2] | want[3]]] = False
        if not alive.any():
            break


def _plain_return(task, params, seed, policy, steps):
    env = gym.make(f"rrls/robust-{task}-v0", max_episode_steps=steps)
    env.set_params(**params)
    obs, _ = env.reset(seed=seed)
    total, done = 0.0, False
    while not done:
        obs, r, term, trunc, _ = env.step(policy(obs[None])[0])
        total += r
        done = term or trunc
    return total


@pytest.mark.parametrize(
    "task, names, low, high",
    [
        ("hopper", ("thighdamping", "timestep"), (0.0, 0.0015), (5.0, 0.003)),
        ("hopper", ("gravity", "footgear", "legcom_x"), (5.0, 100.0, -0.05), (12.0, 250.0, 0.05)),
        ("halfcheetah", ("backthigharmature", "forwardfootfriction"), (0.0, 0.2), (1.0, 1.5)),
        ("ant", ("hip1frictionloss", "torsocom_y"), (0.0, -0.05), (1.0, 0.05)),
    ],
)
def test_evaluate_meshes_every_kind_and_rows_equal_the_plain_loop(task, names, low, high):
    act_dim = ROBUST_ENVS[task]().action_space.shape[0]

    def policy(obs):  # row by row (a matrix product would depend on the batch's BLAS kernel)
        return np.tanh(obs[:, :act_dim] * 0.5 + 0.1)

    box = UncertaintySet(names, low, high)
    steps = 40
    result = evaluate(policy, task, box, mesh=2, episodes=1, workers=1, max_episode_steps=steps)
    assert len(result.episodes) == 2 ** len(names)
    for _, row in result.episodes.iterrows():
        params = {n: row[n] for n in names}
        assert _plain_return(task, params, int(row["seed"]), policy, steps) == row["return"], params


def test_search_worst_case_over_new_kinds():
    def policy(obs):
        return np.zeros((len(obs), 3))

    box = UncertaintySet(("gravity", "thighdamping"), (5.0, 0.0), (12.0, 5.0))
    found = search_worst_case(policy, "hopper", box, budget=6, workers=1, max_episode_steps=30)
    assert 5.0 <= found.params["gravity"] <= 12.0 and 0.0 <= found.params["thighdamping"] <= 5.0
