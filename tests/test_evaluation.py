"""The evaluation engine: every row equals the plain one-episode loop, whatever workers/batch
(the command line and the plots: ``test_evaluate_cli.py``)."""

from __future__ import annotations

import json

import gymnasium as gym
import numpy as np
import pandas as pd
import pytest
from conftest import TASK_KEYS, random_policy

import rrls  # noqa: F401
from rrls.evaluation import (
    BatchInvariant,
    EvaluationResult,
    MLPPolicy,
    PolicyError,
    engine,
    evaluate,
    lanes,
    load_policy,
    resolve_uncertainty,
    scheduling,
)
from rrls.evaluation.lanes import episode_seeds
from rrls.uncertainty import UncertaintySet


def plain_loop(env_id: str, policy, params: dict, seed: int, max_steps: int) -> tuple[float, int]:
    """The issue's reference: make, set_params, reset(seed), policy(obs[None])[0] until done."""
    env = gym.make(env_id, max_episode_steps=max_steps)
    env.set_params(**params)
    obs, _ = env.reset(seed=seed)
    ret, length = 0.0, 0
    while True:
        obs, reward, terminated, truncated, _ = env.step(policy(obs[None])[0])
        ret += reward
        length += 1
        if terminated or truncated:
            return ret, length


# Long-lived tasks get shorter episodes so the whole check stays fast.
STEPS = {"ant": 150, "halfcheetah": 300, "humanoidstandup": 100}


@pytest.mark.exactness
@pytest.mark.parametrize("task", TASK_KEYS)
def test_rows_equal_the_plain_loop(task):
    policy = random_policy(task)
    steps = STEPS.get(task, 1000)
    result = evaluate(
        policy, task, "2d", mesh=2, episodes=2, seed=7, workers=1, max_episode_steps=steps
    )
    assert len(result.episodes) == 8
    for row in result.episodes.itertuples(index=False):
        params = {n: getattr(row, n) for n in result.param_names}
        ret, length = plain_loop(f"rrls/robust-{task}-v0", policy, params, row.seed, steps)
        assert (row.length, row[result.episodes.columns.get_loc("return")]) == (length, ret)


@pytest.mark.parametrize("uncertainty", ["rarl", "nominal"])
def test_force_set_and_nominal_equal_the_plain_loop(uncertainty):
    policy = random_policy("hopper")
    result = evaluate(policy, "hopper", uncertainty, mesh=2, episodes=1, workers=1)
    family = "force" if uncertainty == "rarl" else "robust"
    for row in result.episodes.itertuples(index=False):
        params = {n: getattr(row, n) for n in result.param_names}
        ret, length = plain_loop(f"rrls/{family}-hopper-v0", policy, params, row.seed, 1000)
        assert row.length == length
        assert row[result.episodes.columns.get_loc("return")] == ret
    if uncertainty == "nominal":
        assert len(result.episodes) == 1 and result.param_names == []


@pytest.mark.exactness
def test_results_do_not_depend_on_workers_or_batch_size():
    policy = random_policy("walker")
    runs = [
        evaluate(
            policy, "walker", "3d", mesh=2, episodes=3, seed=1, workers=w, batch_size=b
        ).episodes
        for w, b in [(1, 1), (1, 5), (1, 64), (2, 3), (2, 64)]
    ]
    for other in runs[1:]:
        pd.testing.assert_frame_equal(runs[0], other, check_exact=True)


@pytest.mark.parametrize(("n", "workers"), [(512, 16), (5000, 16), (125, 2), (3, 8), (50, 16)])
def test_plan_work_gives_every_worker_a_balanced_share(n, workers):
    """Fixed 50-row units gave 512 rows to only 11 of 16 workers; shares now differ by <= 1."""
    plan = scheduling.plan_work(n, workers)
    assert plan.workers == min(n, workers)
    sizes = [stop - start for start, stop in plan.shares]
    assert min(sizes) >= 1 and max(sizes) - min(sizes) <= 1 and sum(sizes) == n
    assert [s[0] for s in plan.shares[1:]] == [s[1] for s in plan.shares[:-1]]  # contiguous
    assert plan.lanes == min(lanes.LANES, max(sizes))  # no lane without an episode
    with pytest.raises(ValueError, match="workers must be >= 1"):
        scheduling.plan_work(n, 0)


def _simulate(lengths, workers, lanes=lanes.LANES, late=0, max_steps=1000):
    """Lockstep rounds of ``take_row``: worker ``w`` starts ``w * late`` rounds late.

    Returns each worker's rows and the rounds it ran; checks that every row runs exactly once and
    that a worker is refused a row only when none is left or its owner will start it soon.
    """
    plan = scheduling.plan_work(len(lengths), workers, lanes)
    bounds = scheduling.shared_bounds(plan, max_steps)
    horizon = scheduling.steal_horizon(max_steps)
    live = [[] for _ in range(plan.workers)]  # (steps left, steps done) of each live lane
    rows = [[] for _ in range(plan.workers)]
    busy = [0] * plan.workers
    t = 0
    while t < 10 * sum(lengths) + 100:
        for w in range(plan.workers):
            if t < w * late:
                continue
            live[w] = [(k - 1, d + 1) for k, d in live[w] if k > 1]  # one lockstep step
            while len(live[w]) < plan.lanes:
                r = scheduling.take_row(bounds, w, len(live[w]), horizon)
                if r < 0:
                    for v in range(plan.workers):
                        left = bounds[3 * v + 1] - bounds[3 * v]
                        assert left <= 0 or (live[w] and bounds[3 * v + 2] <= horizon)
                    break
                rows[w].append(r)
                live[w].append((lengths[r], 0))
            full = len(live[w]) == plan.lanes
            bounds[3 * w + 2] = max_steps - max(d for _, d in live[w]) if full else 0
            busy[w] += bool(live[w])
        t += 1
        if not any(live) and t > plan.workers * late:
            break
    assert sorted(r for rs in rows for r in rs) == list(range(len(lengths)))
    return rows, busy


def test_work_stealing_keeps_every_worker_busy_and_balanced():
    """A simulation of 16 workers (no 16 cores needed): equal shares, then single-row stealing."""
    # equal lengths (HalfCheetah): 5000 rows on 16 x 64 lanes; a shared counter (or greedy
    # stealing) handed the last wave's 904 rows as 14 x 64 + 8 + 0, now every worker runs 312-313
    rows, busy = _simulate([1000] * 5000, 16)
    counts = [len(r) for r in rows]
    assert max(counts) - min(counts) <= 1
    assert max(busy) == 5000  # 5 waves of 1000 steps, the least possible
    # 512 rows on 16 workers: 32 each, 32 lanes each (a 50-row unit left 5 workers idle)
    rows, _ = _simulate([100] * 512, 16)
    assert [len(r) for r in rows] == [32] * 16
    # varied lengths and late starters: early workers steal, everyone finishes close together
    rng = np.random.default_rng(0)
    lengths = rng.integers(20, 1000, size=2000).tolist()
    rows, busy = _simulate(lengths, 16, late=30)
    ends = [w * 30 + b for w, b in enumerate(busy)]
    assert max(ends) - min(ends) <= 1000  # at most one episode apart
    assert len(rows[0]) > len(rows[15])  # the first to start stole from the last


@pytest.mark.exactness
def test_results_do_not_depend_on_the_work_split_or_chunk_size(tmp_path):
    """Rows depend only on their seed: any workers, lanes or saving chunk give the same columns."""
    policy = random_policy("hopper")
    box = resolve_uncertainty("hopper", "2d")
    points = box.mesh(3)
    spec = lanes.Rollouts(
        "hopper", "robust", box.names, points, episode_seeds(4, len(points), 3), 200
    )
    runs = [
        engine.run(spec, policy, workers=w, lanes=b, chunk=c, chunk_dir=tmp_path / f"{w}{b}{c}")
        for w, b, c in [(1, 64, 50), (2, 3, 50), (3, 2, 7), (2, 64, 5)]
    ]
    for other in runs[1:]:
        for k, v in runs[0].items():
            np.testing.assert_array_equal(v, other[k])


def test_table_columns_seeds_and_scores():
    policy = random_policy("invertedpendulum")
    result = evaluate(policy, "invertedpendulum", "2d", mesh=3, episodes=4, seed=5, workers=1)
    frame = result.episodes
    assert list(frame.columns) == [
        "point",
        "polemass",
        "cartmass",
        "episode",
        "seed",
        "return",
        "length",
        "terminated",
        "diverged",
    ]
    assert len(frame) == 9 * 4 and frame["seed"].nunique() == 36
    np.testing.assert_array_equal(frame["seed"], episode_seeds(5, 9, 4).reshape(-1))
    assert not np.array_equal(episode_seeds(5, 9, 4), episode_seeds(6, 9, 4))
    # seeds depend on (point, episode) only, not on how many points there are
    np.testing.assert_array_equal(episode_seeds(5, 9, 4)[:4], episode_seeds(5, 4, 4))
    per_point = frame.groupby("point")["return"].mean()
    assert result.worst_case == per_point.min()
    assert result.average_case == pytest.approx(per_point.mean(), rel=1e-12)
    worst = frame[frame["point"] == per_point.idxmin()].iloc[0]
    assert result.worst_point == {"polemass": worst["polemass"], "cartmass": worst["cartmass"]}
    # mesh includes both bounds by default
    assert sorted(frame["polemass"].unique()) == [1.0, 16.0, 31.0]


def test_same_seed_same_numbers_other_seed_other_numbers():
    policy = random_policy("hopper")
    a = evaluate(policy, "hopper", "1d", mesh=2, episodes=2, seed=0, workers=1)
    b = evaluate(policy, "hopper", "1d", mesh=2, episodes=2, seed=0, workers=2)
    c = evaluate(policy, "hopper", "1d", mesh=2, episodes=2, seed=1, workers=1)
    pd.testing.assert_frame_equal(a.episodes, b.episodes)
    assert not np.array_equal(a.episodes["return"], c.episodes["return"])


class FlakyPolicy:
    """A policy that raises after ``fail_after`` calls (an interruption), else ``inner``."""

    def __init__(self, inner, fail_after: int | None = None) -> None:
        self.inner, self.fail_after, self.calls, self.rows = inner, fail_after, 0, 0

    def __call__(self, obs):
        self.calls += 1
        self.rows += len(obs)
        if self.fail_after is not None and self.calls > self.fail_after:
            raise KeyboardInterrupt
        return self.inner(obs)


def test_interrupted_evaluation_resumes_to_the_same_result(tmp_path):
    inner = random_policy("invertedpendulum")
    kwargs = dict(
        task="invertedpendulum",
        uncertainty="2d",
        mesh=4,
        episodes=10,
        seed=3,
        workers=1,
        batch_size=4,
    )  # 160 episodes = 4 chunks of 50, 4 lanes
    counting = FlakyPolicy(inner)
    full = evaluate(counting, **kwargs)

    out = tmp_path / "run"
    with pytest.raises(KeyboardInterrupt):  # killed halfway through
        evaluate(FlakyPolicy(inner, fail_after=counting.calls // 2), out_dir=out, **kwargs)
    saved = sorted((out / "chunks").glob("*.npz"))
    assert 0 < len(saved) < 4 and not (out / "summary.json").exists()

    resumed_policy = FlakyPolicy(inner)
    resumed = evaluate(resumed_policy, out_dir=out, **kwargs)
    pd.testing.assert_frame_equal(full.episodes, resumed.episodes, check_exact=True)
    assert resumed_policy.rows < 0.9 * counting.rows  # the saved chunks were not run again

    summary = json.loads((out / "summary.json").read_text())
    assert summary["worst_case"] == full.worst_case
    assert {"task", "uncertainty", "mesh", "episodes", "seed", "versions"} <= set(summary)
    loaded = EvaluationResult.load(out)
    pd.testing.assert_frame_equal(loaded.episodes, full.episodes, check_dtype=False)
    assert loaded.worst_case == full.worst_case and loaded.average_case == full.average_case


def test_resume_refuses_other_arguments(tmp_path):
    policy = random_policy("invertedpendulum")
    evaluate(policy, "invertedpendulum", "1d", mesh=2, episodes=1, out_dir=tmp_path, workers=1)
    with pytest.raises(ValueError, match="different arguments.*episodes"):
        evaluate(policy, "invertedpendulum", "1d", mesh=2, episodes=2, out_dir=tmp_path, workers=1)
    with pytest.raises(ValueError, match="policy_fingerprint"):
        evaluate(
            random_policy("invertedpendulum", seed=9),
            "invertedpendulum",
            "1d",
            mesh=2,
            episodes=1,
            out_dir=tmp_path,
            workers=1,
        )


@pytest.mark.parametrize("workers", [1, 2])
def test_nan_actions_name_the_point_and_step(workers):
    inner = random_policy("hopper")

    def nan_late(obs):
        actions = inner(obs)
        actions[np.abs(obs[:, 0] - 1.25) > 0.05] = np.nan  # once the torso has moved a bit
        return actions

    with pytest.raises(
        PolicyError, match=r"non-finite.*mesh point \d+ \{'worldfriction'.*step \d+"
    ):
        evaluate(nan_late, "hopper", "1d", mesh=2, episodes=1, workers=workers)


def test_wrong_action_shape_is_refused_before_rollouts():
    with pytest.raises(PolicyError, match=r"expected \(2, 3\)"):
        evaluate(lambda obs: np.zeros((len(obs), 2)), "hopper", "1d", mesh=2, workers=1)

    calls = []

    def shape_changes(obs):  # right at first, then wrong mid-evaluation
        calls.append(len(obs))
        return np.zeros((len(obs), 3 if len(calls) < 50 else 4))

    with pytest.raises(PolicyError, match=r"shape .*mesh point .*step"):
        evaluate(shape_changes, "hopper", "1d", mesh=2, episodes=1, workers=1)


def test_divergence_is_recorded_not_raised():
    huge = UncertaintySet(("torsoforce_x",), [0.0], [1e12], [0.0], "hopper/huge-force")
    zero = lambda obs: np.zeros((len(obs), 3))  # noqa: E731
    with pytest.warns(UserWarning, match="diverged"):
        result = evaluate(zero, "hopper", huge, mesh=2, episodes=1, workers=1)
    frame = result.episodes
    assert frame["diverged"].tolist() == [False, True]
    assert np.isfinite(frame["return"]).all()
    assert result.summary()["diverged"] == 1


def test_non_batch_invariant_policy_warns():
    rng = np.random.default_rng(0)
    w = rng.normal(size=(11, 3)).astype(np.float32)

    def leaky(obs):  # its output depends on the batch: a row-order sum over the batch
        return np.tanh(obs.astype(np.float32) @ w) + 1e-7 * len(obs)

    with pytest.warns(UserWarning, match="BatchInvariant"):
        evaluate(leaky, "hopper", "1d", mesh=2, episodes=1, workers=1)
    wrapped = BatchInvariant(leaky)
    np.testing.assert_array_equal(wrapped(np.ones((70, 11)))[3], wrapped(np.ones((1, 11)))[0])


def test_mlp_policy_file_round_trip_and_refusals(tmp_path):
    policy = MLPPolicy.random(11, 3, hidden=(16,), seed=2)
    path = policy.save(tmp_path / "policy.npz")
    loaded = load_policy(path)
    obs = np.random.default_rng(0).normal(size=(5, 11))
    np.testing.assert_array_equal(policy(obs), loaded(obs))
    np.savez(tmp_path / "other.npz", w=np.zeros(3))
    with pytest.raises(ValueError, match="not an rrls MLP policy"):
        load_policy(tmp_path / "other.npz")
    with pytest.raises(FileNotFoundError):
        load_policy(tmp_path / "missing.npz")
    with pytest.raises(ValueError, match="expected observations of shape"):
        policy(np.zeros((2, 7)))


@pytest.mark.exactness
def test_mlp_policy_is_batch_invariant_at_large_batches():
    policy = MLPPolicy.random(17, 6, seed=0)  # 256-256, the benchmark's size
    obs = np.random.default_rng(4).normal(size=(1000, 17))
    batch = policy(obs)
    for i in (0, 63, 64, 500, 999):
        np.testing.assert_array_equal(batch[i], policy(obs[i : i + 1])[0])


def test_bad_arguments():
    policy = random_policy("hopper")
    with pytest.raises(ValueError, match="valid tasks"):
        evaluate(policy, "cartpole", "1d")
    with pytest.raises(ValueError, match="valid: 1d, 2d, rarl"):
        evaluate(policy, "invertedpendulum", "3d")
    with pytest.raises(ValueError, match="episodes"):
        evaluate(policy, "hopper", "1d", episodes=0)


# -- worst-case search -------------------------------------------------------------------------
@pytest.mark.exactness
def test_search_worst_case_trace_budget_and_consistency():
    from rrls.evaluation import search_worst_case

    policy = random_policy("hopper")
    found = search_worst_case(policy, "hopper", "2d", budget=30, episodes=2, seed=0, workers=1)
    trace = found.trace
    assert found.evaluations == len(trace) <= 30 and found.episode_evaluations == 2 * len(trace)
    assert list(trace.columns) == [
        "generation",
        "worldfriction",
        "torsomass",
        "mean_return",
        "best_so_far",
    ]
    assert found.value == trace["mean_return"].min() == trace["best_so_far"].iloc[-1]
    assert found.uncertainty.contains(trace[["worldfriction", "torsomass"]].to_numpy()).all()
    # the reported value is what the engine gives at that point with the same (common) seeds
    point = UncertaintySet.from_bounds({k: [v, v] for k, v in found.params.items()})
    again = evaluate(policy, "hopper", point, mesh=1, episodes=2, seed=0, workers=1)
    assert again.worst_case == found.value
    # reproducible
    other = search_worst_case(policy, "hopper", "2d", budget=30, episodes=2, seed=0, workers=2)
    pd.testing.assert_frame_equal(trace, other.trace)


@pytest.mark.slow
def test_search_beats_the_grid_with_fewer_episodes():
    """The demonstration of the issue (also printed by benchmarks/worst_case_search.py)."""
    from rrls.evaluation import search_worst_case

    env = gym.make("rrls/robust-hopper-v0")
    policy = MLPPolicy.random(
        env.observation_space.shape[0], env.action_space.shape[0], hidden=(64, 64), seed=1
    )
    grid = evaluate(policy, "hopper", "3d", mesh=10, episodes=1, seed=0)
    found = search_worst_case(policy, "hopper", "3d", budget=400, episodes=1, seed=0)
    assert found.episode_evaluations < len(grid.episodes)
    assert found.value < grid.worst_case


# -- dynamic evaluation (Table 6) ----------------------------------------------------------------
@pytest.mark.parametrize(
    "game, uncertainty",
    [("adversarial", "3d"), ("adversarial", "rarl"), ("nr", "3d"), ("pr", "3d")],
)
def test_dynamic_evaluation_equals_the_plain_two_player_loop(game, uncertainty):
    from rrls.evaluation import evaluate_dynamic, make_dynamic_env

    protagonist = random_policy("hopper")
    env = make_dynamic_env("hopper", game, uncertainty, alpha=0.3)
    adversary = MLPPolicy.random(11, env.action_space[1].shape[0], hidden=(16,), seed=2)
    result = evaluate_dynamic(
        protagonist, adversary, "hopper", game, uncertainty, episodes=4, alpha=0.3, batch_size=3
    )
    assert len(result.episodes) == 4
    assert result.mean == pytest.approx(result.episodes["return"].mean())
    for row in result.episodes.itertuples(index=False):
        obs, _ = env.reset(seed=row.seed)
        ret, length = 0.0, 0
        while True:
            pair = (protagonist(obs[None])[0], adversary(obs[None])[0])
            obs, reward, terminated, truncated, _ = env.step(pair)
            ret, length = ret + reward, length + 1
            if terminated or truncated:
                break
        assert (row[result.episodes.columns.get_loc("return")], row.length) == (ret, length)


def test_an_adversary_lowers_the_return():
    from rrls.evaluation import evaluate_dynamic

    # a pole left alone falls after ~20 steps; a constant 3 N sideways push on it (either way)
    # topples it in about half the time: the adversary must *lower* the return
    still = lambda o: np.zeros((len(o), 1))  # noqa: E731
    game = ("invertedpendulum", "adversarial", "rarl")
    passive = evaluate_dynamic(still, lambda o: np.zeros((len(o), 2)), *game, episodes=3)
    assert passive.mean > 15
    for push in (1.0, -1.0):
        adversary = lambda o, p=push: np.tile([p, 0.0], (len(o), 1))  # noqa: E731
        pushing = evaluate_dynamic(still, adversary, *game, episodes=3)
        assert pushing.mean < 0.75 * passive.mean


# -- adapters, CLI and plots --------------------------------------------------------------------
def test_sb3_like_models_are_adapted():
    from rrls.evaluation import SB3Policy, as_policy

    inner = random_policy("hopper")

    class FakeSB3:
        policy = object()

        def predict(self, obs, deterministic=False):
            assert deterministic
            return inner(obs), None

    adapted = as_policy(FakeSB3())
    assert isinstance(adapted, SB3Policy)
    obs = np.random.default_rng(0).normal(size=(3, 11))
    np.testing.assert_array_equal(adapted(obs), inner(obs))
    with pytest.raises(TypeError, match="cannot use int as a policy"):
        as_policy(3)


def test_torch_modules_are_adapted():
    torch = pytest.importorskip("torch")
    from rrls.evaluation import TorchPolicy, as_policy

    torch.manual_seed(0)
    module = torch.nn.Sequential(
        torch.nn.Linear(11, 32), torch.nn.ReLU(), torch.nn.Linear(32, 3), torch.nn.Tanh()
    )
    adapted = as_policy(module)
    assert isinstance(adapted, TorchPolicy)
    obs = np.random.default_rng(0).normal(size=(100, 11))
    batch = adapted(obs)
    np.testing.assert_array_equal(batch[70], adapted(obs[70:71])[0])
    result = evaluate(module, "hopper", "1d", mesh=2, episodes=1, workers=2)
    ret, length = plain_loop(
        "rrls/robust-hopper-v0",
        adapted,
        {"worldfriction": 0.1},
        int(result.episodes["seed"][0]),
        1000,
    )
    assert (result.episodes["length"][0], result.episodes["return"][0]) == (length, ret)
