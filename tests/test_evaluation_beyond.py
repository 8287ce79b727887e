"""``evaluate`` over disruptors, schedule families, context and splits: rows = the plain loop."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import rrls
from rrls.evaluation import EvaluationResult, MLPPolicy, evaluate
from rrls.evaluation.stack import EnvStack
from rrls.uncertainty import Split, UncertaintySet
from rrls.wrappers import ContextObservation, Drift, ScheduledParams, ScheduleFamily, disrupt

STEPS = 200


def policy_for(obs_dim: int, seed: int = 3) -> MLPPolicy:
    return MLPPolicy.random(obs_dim, 3, hidden=(32, 32), seed=seed)


def plain_loop(wrap, policy, params: dict, seed: int) -> tuple[float, int]:
    """The reference: the registered env in the same wrappers, set_params, reset(seed), step."""
    env = wrap(gym.make("rrls/robust-hopper-v0", max_episode_steps=STEPS))
    env.set_params(**params)
    obs, _ = env.reset(seed=seed)
    ret, length = 0.0, 0
    while True:
        obs, reward, terminated, truncated, _ = env.step(policy(obs[None])[0])
        ret += reward
        length += 1
        if terminated or truncated:
            return ret, length


def assert_rows_equal_plain_loop(result: EvaluationResult, wrap, policy) -> None:
    for row in result.episodes.itertuples(index=False):
        params = {n: getattr(row, n) for n in result.param_names}
        ret, length = plain_loop(wrap, policy, params, row.seed)
        assert (row.length, row[result.episodes.columns.get_loc("return")]) == (length, ret)


@pytest.mark.exactness
@pytest.mark.parametrize("workers", [1, 2])
def test_disruptor_strengths_meshed_jointly_with_dynamics(workers):
    box = UncertaintySet.from_bounds({"torsomass": (1.0, 5.0), "obsnoise": (0.0, 0.2)})
    policy = policy_for(11)
    kw = dict(mesh=2, episodes=2, seed=1, max_episode_steps=STEPS)
    result = evaluate(policy, "hopper", box, workers=workers, **kw)
    assert result.param_names == ["torsomass", "obsnoise"] and len(result.episodes) == 8
    assert_rows_equal_plain_loop(result, lambda env: disrupt(env, obsnoise=0.0), policy)
    by_noise = result.per_point.groupby("obsnoise")["mean_return"].mean()
    assert by_noise.loc[0.0] != by_noise.loc[0.2]  # the strength reaches the rows
    if workers == 2:  # same numbers whatever the workers
        assert result.episodes.equals(evaluate(policy, "hopper", box, workers=1, **kw).episodes)


def test_disruptors_alone_fixed_and_meshed():
    policy = policy_for(11)
    result = evaluate(
        policy,
        "hopper",
        "nominal",
        mesh=3,
        episodes=1,
        workers=1,
        max_episode_steps=STEPS,
        disruptors={"actiondelay": (0, 2), "rewardnoise": 0.5},
    )
    assert result.param_names == ["actiondelay"]
    assert result.episodes["actiondelay"].tolist() == [0.0, 1.0, 2.0]
    assert result.config["disruptors"] == {"actiondelay": 0.0, "rewardnoise": 0.5}
    assert_rows_equal_plain_loop(
        result, lambda env: disrupt(env, actiondelay=0, rewardnoise=0.5), policy
    )


def test_schedule_family_is_what_is_meshed():
    family = ScheduleFamily("drift", rate=[0.005, 0.02], direction=[-1, 1])
    policy = policy_for(11)
    result = evaluate(
        policy, "hopper", "2d", episodes=1, workers=1, max_episode_steps=STEPS, schedule=family
    )
    assert result.param_names == ["drift_rate", "drift_direction"]
    assert result.per_point[["drift_rate", "drift_direction"]].values.tolist() == [
        [0.005, -1.0],
        [0.005, 1.0],
        [0.02, -1.0],
        [0.02, 1.0],
    ]
    box = rrls.get_uncertainty_set("hopper", "2d")
    assert result.config["schedule"] == {"kind": "drift", "grid": family.to_json()["grid"]}
    assert_rows_equal_plain_loop(result, lambda env: ScheduledParams(env, box, Drift()), policy)
    assert result.per_point["mean_return"].nunique() > 1


def test_context_policy_sees_the_parameters():
    box = UncertaintySet.from_bounds({"torsomass": (1.0, 5.0)})
    policy = policy_for(12)
    result = evaluate(
        policy,
        "hopper",
        box,
        mesh=3,
        episodes=1,
        workers=1,
        context=True,
        max_episode_steps=STEPS,
    )
    assert_rows_equal_plain_loop(result, lambda env: ContextObservation(env, box), policy)
    with pytest.raises(ValueError, match=r"expected \(2, 3\)|\(2, 11\)"):
        evaluate(policy, "hopper", box, mesh=2, episodes=1, workers=1)


@pytest.mark.parametrize("kind", ["interpolation", "extrapolation"])
def test_splits_partition_the_mesh_exactly(kind):
    box = rrls.get_uncertainty_set("hopper", "3d")
    make = Split.interpolation if kind == "interpolation" else Split.extrapolation
    for fraction in (0.3, 0.5, 0.8):
        split = make(box, fraction)
        for n in (2, 3, 5, 10):
            mesh = box.mesh(n)
            ind, ood = split.in_distribution(mesh), split.out_of_distribution(mesh)
            assert ind.dtype == bool and np.all(ind ^ ood)  # each point in exactly one part
            assert ind.sum() + ood.sum() == len(mesh)
            inside = np.all((mesh >= split.region.low) & (mesh <= split.region.high), axis=1)
            assert np.array_equal(ind, ~inside if kind == "interpolation" else inside)
    rng = np.random.default_rng(0)
    split = make(box, 0.5)
    draws = np.array([box.to_array(split.sample_train(box, rng)) for _ in range(300)])
    assert np.all(split.in_distribution(draws)) and np.all(box.contains(draws))
    assert Split.from_json(split.to_json()).region == split.region


def test_evaluate_and_report_give_in_and_out_of_distribution_scores(tmp_path):
    box = rrls.get_uncertainty_set("hopper", "2d")
    split = Split.extrapolation(box, inner={"worldfriction": (0.5, 2.0), "torsomass": (1, 2)})
    policy = policy_for(11)
    result = evaluate(
        policy,
        "hopper",
        box,
        mesh=4,
        episodes=1,
        workers=1,
        split=split,
        max_episode_steps=STEPS,
        out_dir=tmp_path / "eval",
    )
    table = result.per_point
    expected = split.in_distribution(table[list(box.names)].to_numpy())
    assert np.array_equal(table["in_distribution"].to_numpy(), expected)
    scores = result.split_scores()
    ind, ood = table[expected]["mean_return"], table[~expected]["mean_return"]
    assert scores["worst_case_id"] == ind.min() and scores["average_case_id"] == ind.mean()
    assert scores["worst_case_ood"] == ood.min() and scores["average_case_ood"] == ood.mean()
    assert scores["points_id"] + scores["points_ood"] == len(table) == 16
    loaded = EvaluationResult.load(tmp_path / "eval")
    assert loaded.split_scores() == scores and loaded.config["split"] == split.to_json()
    summary = result.summary()
    assert summary["worst_case_ood"] == scores["worst_case_ood"]


def test_bad_beyond_arguments():
    policy = policy_for(11)
    kw = dict(mesh=2, episodes=1, workers=1)
    with pytest.raises(ValueError, match="unknown disruptor 'noise'"):
        evaluate(policy, "hopper", "1d", disruptors={"noise": 0.1}, **kw)
    with pytest.raises(ValueError, match="obsnoise is a standard deviation"):
        evaluate(policy, "hopper", "1d", disruptors={"obsnoise": (-1, 0)}, **kw)
    with pytest.raises(ValueError, match="the mesh has obsdelay=0.5: .*whole number"):
        evaluate(policy, "hopper", "1d", disruptors={"obsdelay": (0, 1)}, mesh=3, episodes=1)
    with pytest.raises(TypeError, match="ScheduleFamily"):
        evaluate(policy, "hopper", "1d", schedule=Drift(0.1), **kw)
    with pytest.raises(ValueError, match="a schedule needs a set"):
        evaluate(policy, "hopper", "nominal", schedule=ScheduleFamily("drift", rate=[0.1]), **kw)
    box = rrls.get_uncertainty_set("hopper", "1d")
    with pytest.raises(ValueError, match="does not apply to a schedule family"):
        evaluate(
            policy,
            "hopper",
            box,
            schedule=ScheduleFamily("drift", rate=[0.1]),
            split=Split.interpolation(box),
            **kw,
        )
    other = UncertaintySet.from_bounds({"torsomass": (0.1, 3.0)})
    with pytest.raises(ValueError, match="the mesh does not vary"):
        evaluate(policy, "hopper", box, split=Split.interpolation(other), **kw)


def test_env_stack_is_hashable_and_records_itself():
    stack = EnvStack(disruptors=(("obsnoise", 0.1),))
    assert hash(stack) == hash(EnvStack(disruptors=(("obsnoise", 0.1),)))
    assert stack.to_json() == {"disruptors": {"obsnoise": 0.1}} and not stack.empty
