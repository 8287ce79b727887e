"""Several algorithms' runs on one MuJoCo Warp twin, on warp's CPU device: a twin whose worlds
each have their own mode (``WarpTwin(modes=...)``: nominal, a fresh point per episode, the
caller's point, the adversary's point every step) gives every world the numbers it has in a
twin of its mode alone, bit for bit, though MuJoCo Warp recomputes every world's derived
constants whenever one world's point is written."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("warp")
pytest.importorskip("mujoco_warp")

from rrls.twin import WarpTwin

#: the long end-to-end tier (.ci/run runs it after the default suite)
pytestmark = pytest.mark.e2e

TASK, SET = "hopper", "3d"
MODES = ("nominal", "random", "chosen", "adversary", "nominal")
SEEDS = [11, 12, 13, 14, 15]
FLAGS = {
    "nominal": {},
    "random": {"domain_randomization": True, "pool": 0},
    "chosen": {"chosen": True},
    "adversary": {"adversary": True},
}


def _run(twin: WarpTwin, actions: np.ndarray, point: np.ndarray, first: int) -> list:
    """``len(actions)`` steps (the chosen world's point written after every reset), each step's
    observations, rewards, ends and the worlds' points."""
    out = []
    twin.reset()
    if "chosen" in twin.world_modes:
        twin.set_points(point, first)
    for a in actions:
        obs, reward, term, trunc, _ = twin.step(a)
        if "chosen" in twin.world_modes and (term | trunc).any():
            twin.set_points(point, first)
        out.append((obs.copy(), reward.copy(), term | trunc, twin.points()))
    return out


@pytest.mark.warp
def test_each_world_of_a_mixed_twin_is_its_mode_alone():
    mixed = WarpTwin(TASK, len(MODES), SET, modes=MODES, seed=SEEDS, device="cpu")
    nu, dim = mixed.nu, mixed.box.dim
    assert mixed.single_action_space.shape == (nu + dim,)  # an adversary: the joint action
    rng = np.random.default_rng(0)
    steps = 120  # hopper falls within ~20-60 random steps: every world resets on the way
    joint = rng.uniform(-1, 1, (steps, len(MODES), nu + dim)).astype(np.float32)
    point = np.array([[0.5 * (lo + hi) for lo, hi in zip(mixed.box.low, mixed.box.high)]])
    chosen = MODES.index("chosen")
    together = _run(mixed, joint, point, chosen)
    for w, mode in enumerate(MODES):
        alone = WarpTwin(TASK, 1, SET, seed=[SEEDS[w]], device="cpu", **FLAGS[mode])
        width = alone.single_action_space.shape[0]
        mine = _run(alone, joint[:, w : w + 1, :width], point, 0)
        for step, (a, b) in enumerate(zip(mine, together)):
            for x, y in zip(a, b):
                assert np.array_equal(x[0], y[w]), f"world {w} ({mode}), step {step + 1}"
        ends = sum(int(e[2][0]) for e in mine)
        assert ends >= 1, f"world {w} ({mode}) never reset in {steps} steps"
        alone.close()
    points = np.array([p[3] for p in together])
    assert not np.array_equal(points[0, 1], points[-1, 1])  # DR drew another point
    assert np.ptp(points[:, 3], axis=0).max() > 0  # the adversary moved its point
    mixed.close()


@pytest.mark.warp
def test_modes_are_checked_in_one_line():
    with pytest.raises(ValueError, match="world mode 'dr'; valid: nominal, random"):
        WarpTwin(TASK, 2, SET, modes=("nominal", "dr"), device="cpu")
    with pytest.raises(ValueError, match="1 modes for 2 worlds"):
        WarpTwin(TASK, 2, SET, modes=("nominal",), device="cpu")
    with pytest.raises(ValueError, match="modes= replaces"):
        WarpTwin(TASK, 1, SET, modes=("random",), domain_randomization=True, device="cpu")
    twin = WarpTwin(TASK, 2, SET, modes=("chosen", "nominal"), device="cpu")
    with pytest.raises(ValueError, match="set_points needs chosen worlds"):
        twin.set_points(np.zeros((1, twin.box.dim)) + twin.box.nominal, 1)
    with pytest.raises(ValueError, match="within the twin's 2 worlds"):
        twin.set_points(np.zeros((3, twin.box.dim)))
    twin.close()


STEPS, STARTS = 60, 20
HYPER = {"learning_starts": STARTS, "batch_size": 16, "hidden": (16, 16)}
ALGOS = ("td3", "dr", "rarl", "nrmdp", "m2td3")  # the paper's five baselines


@pytest.mark.warp
@pytest.mark.exactness  # batched updates: .ci/run repeats it on the other CPU kernels
def test_the_papers_baselines_train_on_one_twin_as_each_alone():
    """A run's numbers do not depend on what else shares its twin: the five baselines' runs
    on one twin (each algorithm's worlds in its mode, its learner updating its own runs, one
    twin step for all) give each run the episodes and the policy it has trained alone."""
    from rrls.agents.on_twin import train_on_twin, train_together

    seeds = {"td3": (0, 1), "dr": (2,), "rarl": (3,), "nrmdp": (4,), "m2td3": (5, 6)}
    hyper = {a: dict(HYPER) for a in ALGOS}
    hyper["m2td3"]["learning_starts"] = 30  # its own warm-up: the groups need not agree
    options = {"device": "cpu", "block": 16, "progress_every": STEPS}
    seen = []
    together = train_together(
        seeds,
        "invertedpendulum",
        STEPS,
        hyper=hyper,
        on_progress=lambda step, returns: seen.append((step, sorted(returns))),
        **options,
    )
    assert seen == [(STEPS, sorted(ALGOS))]
    obs = np.random.default_rng(0).normal(size=(5, 4))
    for algo in ALGOS:
        alone = train_on_twin(
            algo, "invertedpendulum", seeds[algo], STEPS, hyper=hyper[algo], **options
        )
        mine = together[algo]
        assert mine.returns == alone.returns and all(mine.returns), algo
        for a, b in zip(alone.policies, mine.policies):
            np.testing.assert_array_equal(a(obs), b(obs), err_msg=algo)


@pytest.mark.warp
def test_train_together_refuses_in_one_line():
    from rrls.agents.on_twin import train_together

    with pytest.raises(ValueError, match="algos: give at least one"):
        train_together({}, "invertedpendulum", 10, device="cpu")
    with pytest.raises(ValueError, match="seeds of dr: give at least one"):
        train_together({"td3": (0,), "dr": ()}, "invertedpendulum", 10, device="cpu")
    with pytest.raises(ValueError, match="hyper names sac; valid: td3"):
        train_together({"td3": (0,)}, "invertedpendulum", 10, device="cpu", hyper={"sac": {}})


def _twin_run(algo: str, seed: int, where, steps: int, eval_every: int = 50_000):
    """A small ``rrls train --simulator warp`` run on warp's CPU device, in ``where``."""
    from rrls.agents import TrainConfig

    return TrainConfig(
        algo=algo,
        task="invertedpendulum",
        seed=seed,
        steps=steps,
        out=str(where / f"{algo}-{seed}"),
        device="cpu",
        simulator="warp",
        checkpoint_every=45,
        eval_every=eval_every,
        eval_episodes=1,
        hyper=dict(HYPER),
    )


@pytest.mark.warp
@pytest.mark.exactness  # batched updates: .ci/run repeats it on the other CPU kernels
def test_rrls_runs_of_several_algorithms_share_a_twin_and_write_their_own_runs(tmp_path):
    """``train_group`` given runs of several algorithms trains them on one twin, each with its
    own driver and run directory (curves, periodic evaluations, checkpoint, policy), each the
    run its algorithm writes alone."""
    from conftest import policy_arrays

    from rrls.agents import train_group
    from rrls.agents.run import read_checkpoint

    def config(algo: str, seed: int, where: str):
        return _twin_run(algo, seed, tmp_path / where, steps=100, eval_every=70)

    runs = [("td3", 0), ("dr", 1), ("m2td3", 2), ("rarl", 3)]
    shared = train_group([config(a, s, "shared") for a, s in runs])
    for (algo, seed), path in zip(runs, shared):
        alone = train_group([config(algo, seed, "alone")])[0]
        for name in ("scalars.csv",):
            rows = [
                [r for r in (p / name).read_text().splitlines() if "steps_per_second" not in r]
                for p in (alone, path)
            ]
            assert rows[0] == rows[1] and any(",eval/" in r for r in rows[0]), algo
        a, b = policy_arrays(alone), policy_arrays(path)
        assert a.keys() == b.keys() and all(np.array_equal(a[k], b[k]) for k in a), algo
        saved = [read_checkpoint(p / "checkpoint.pt") for p in (alone, path)]
        assert saved[0]["step"] == saved[1]["step"] == 90
        assert saved[0]["twin_episode"] == saved[1]["twin_episode"], algo


@pytest.mark.warp
def test_runs_that_cannot_share_a_twin_are_refused_in_one_line(tmp_path):
    from rrls.agents import TrainConfig, train_group

    base = {"task": "invertedpendulum", "steps": 10, "device": "cpu", "simulator": "warp"}
    mixed = [TrainConfig(algo="td3", **base), TrainConfig(algo="dr", **{**base, "steps": 20})]
    with pytest.raises(ValueError, match="these differ: steps"):
        train_group(mixed)
    cpu = [
        TrainConfig(algo="td3", task="invertedpendulum"),
        TrainConfig(algo="dr", task="invertedpendulum"),
    ]
    with pytest.raises(ValueError, match="only on the Warp twin"):
        train_group(cpu)


@pytest.mark.warp
def test_a_shared_twin_group_killed_and_resumed_is_each_run_killed_and_resumed_alone(tmp_path):
    """Killed right after a checkpoint and resumed, each run of a shared twin continues as it
    does killed and resumed alone: every group checkpoints at the step before any stops, and
    the resumed group shares its twin again (its episodes in progress begun anew, as a resumed
    twin run's are)."""
    from conftest import policy_arrays, stopping_at

    from rrls.agents import Interrupted, train_group

    def configs(runs, where: str) -> list:
        return [_twin_run(algo, seed, tmp_path / where, steps=90) for algo, seed in runs]

    def cut_and_resume(runs, where: str):
        with stopping_at(45), pytest.raises(Interrupted):
            train_group(configs(runs, where))
        return train_group(configs(runs, where), resume=True)

    runs = [("td3", 0), ("m2td3", 1), ("rarl", 2)]
    shared = cut_and_resume(runs, "shared")
    for run, path in zip(runs, shared):
        alone = cut_and_resume([run], f"alone-{run[0]}")[0]
        a, b = policy_arrays(alone), policy_arrays(path)
        assert a.keys() == b.keys() and all(np.array_equal(a[k], b[k]) for k in a), run
