"""The MuJoCo Warp twin on warp's CPU device: each world against CPU MuJoCo at its own point,
Gymnasium v5's formulas, autoreset, seeds, and the refusals. The first test of a task compiles
MuJoCo Warp's kernels (about a minute each on a 2-core machine, cached on disk after)."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("warp")
pytest.importorskip("mujoco_warp")

from conftest import e2e_after_first

from rrls.envs import resolve
from rrls.twin import DIVERGES, REFUSED, TWIN_TASKS, WarpTwin
from rrls.twin.agreement import TWIN_KINDS, divergence, kind_set
from rrls.twin.env import default_set

pytestmark = pytest.mark.warp
# float32 against float64 (MEASURED: <= 1.5e-7 after one env step, <= 6e-7 after ten)
QPOS_1, QPOS_10, REWARD = 1e-5, 1e-4, 1e-3


def twin(task: str, n: int = 4, **kwargs):
    return WarpTwin(task, n, device="cpu", **kwargs)


@pytest.mark.parametrize("task", e2e_after_first([t for t in TWIN_TASKS if t not in DIVERGES]))
def test_each_world_follows_cpu_mujoco_at_its_own_point(task):
    d = divergence(task, default_set(task), worlds=4, steps=10)
    assert d.qpos[0] < QPOS_1, d.qpos
    assert np.nanmax(d.qpos) < QPOS_10, d.qpos
    assert np.nanmax(d.reward) < REWARD, d.reward
    assert d.termination_mismatches == 0


@pytest.mark.e2e
def test_the_ant_agrees_until_its_feet_land_and_parts_after_as_documented():
    d = divergence("ant", "3d", worlds=4, steps=10)
    assert d.qpos[:2].max() < QPOS_1, d.qpos  # in the air
    assert d.qpos[9] > 1e-2, d.qpos  # DIVERGES["ant"]: the docs say so
    assert "contact" in DIVERGES["ant"]


@pytest.mark.parametrize("kind", e2e_after_first(list(TWIN_KINDS)))
def test_every_parameter_kind_reaches_its_world(kind):
    d = divergence("hopper", kind_set("hopper", kind), worlds=4, steps=10)
    assert d.qpos[0] < QPOS_1 and np.nanmax(d.qpos) < QPOS_10, d.qpos
    assert d.termination_mismatches == 0


@pytest.mark.slow
@pytest.mark.parametrize("task", [t for t in TWIN_TASKS if t not in ("hopper", *DIVERGES)])
def test_every_kind_of_every_task(task):
    for kind in TWIN_KINDS:
        try:
            box = kind_set(task, kind)
        except ValueError:
            continue
        d = divergence(task, box, worlds=4, steps=10)
        assert d.qpos[0] < QPOS_1, (kind, d.qpos)
        # HalfCheetah's contacts amplify float32 rounding fastest (measured: up to 2.7e-4
        # after ten steps, friction loss; docs/results/twin/check.csv)
        bound = 1e-3 if task == "halfcheetah" else QPOS_10
        assert np.nanmax(d.qpos) < bound, (kind, d.qpos)


def test_a_twin_without_the_points_is_told_apart():
    """The check can fail: worlds left at the nominal model drift from CPU envs at the points
    within ten steps by far more than the tolerance."""
    box = resolve("hopper", "3d").box
    points = np.array([box.low, box.high, box.low, box.high])
    tw = twin("hopper", 4, uncertainty="3d")  # nominal: no points given
    tw.reset()
    qpos, qvel = tw.state()
    actions = np.full((4, 3), 0.5, dtype=np.float32)
    for _ in range(10):
        tw.step(actions)
    got, _ = tw.state()
    envs_q = []
    for w in range(4):
        env = resolve("hopper", "3d").make_env()
        env.reset(seed=0)
        env.set_params(**dict(zip(box.names, points[w], strict=True)))
        env.set_state(qpos[w].astype(np.float64), qvel[w].astype(np.float64))
        for _ in range(10):
            env.step(actions[w])
        envs_q.append(env.data.qpos.copy())
    assert np.abs(got - np.array(envs_q)).max() > 100 * QPOS_10


@pytest.mark.parametrize("task", list(TWIN_TASKS))
def test_the_first_observation_is_the_cpu_envs_at_the_same_state(task):
    tw = twin(task, 2)
    obs, _ = tw.reset()
    qpos, qvel = tw.state()
    assert obs.shape == (2, *tw.single_observation_space.shape)
    for w in range(2):
        env = resolve(task, default_set(task)).make_env()
        env.reset(seed=0)
        env.set_state(qpos[w].astype(np.float64), qvel[w].astype(np.float64))
        np.testing.assert_allclose(obs[w], env._get_obs(), atol=1e-6)


def test_reset_noise_is_gymnasiums_and_each_worlds_stream_is_its_own():
    a, _ = twin("halfcheetah", 2, seed=3).reset()
    b, _ = twin("halfcheetah", 5, seed=3).reset()
    c, _ = twin("halfcheetah", 2, seed=4).reset()
    np.testing.assert_array_equal(a, b[:2])  # world w's draws do not depend on the count
    assert not np.allclose(a, c)
    # HalfCheetah v5: qpos + U(-0.1, 0.1), qvel 0.1 * N(0, 1)
    q = a[:, :8]  # qpos[1:] (nominal 0)
    assert np.abs(q).max() <= 0.1 and np.abs(q).max() > 0.01


def test_same_step_autoreset_returns_the_next_episodes_first_observation():
    tw = twin("halfcheetah", 3, max_episode_steps=2)
    tw.reset(seed=0)
    zeros = np.zeros((3, 6), dtype=np.float32)
    _, _, term, trunc, _ = tw.step(zeros)
    assert not trunc.any() and not term.any()
    obs, _, term, trunc, info = tw.step(zeros)
    assert trunc.all() and not term.any()
    assert info["_final_obs"].all()
    assert not np.allclose(obs, info["final_obs"])  # a fresh episode
    _, _, _, trunc, _ = tw.step(zeros)
    assert not trunc.any()  # the step counts restarted


def test_an_unhealthy_hopper_terminates_and_is_reset():
    tw = twin("hopper", 2)
    tw.reset(seed=0)
    qpos, qvel = tw.state()
    qpos[0, 1] = 0.3  # z below the healthy range (0.7, inf)
    tw.set_state(qpos, qvel)
    _, reward, term, _, info = tw.step(np.zeros((2, 3), dtype=np.float32))
    assert term.tolist() == [True, False]
    assert reward[0] < 0.5 and reward[1] > 0.5  # no healthy reward for world 0
    assert tw.state()[0][0, 1] > 1.2  # back to the start


def test_domain_randomization_draws_a_new_point_per_episode_from_the_pool():
    tw = twin("hopper", 4, domain_randomization=True, pool=64, seed=1)
    tw.reset()
    first = tw.points()
    box = resolve("hopper", "3d").box
    assert all(box.contains(p) for p in first)
    qpos, qvel = tw.state()
    qpos[:, 1] = 0.3
    tw.set_state(qpos, qvel)
    tw.step(np.zeros((4, 3), dtype=np.float32))  # every world ends and redraws
    assert not np.allclose(tw.points(), first)
    again = twin("hopper", 4, domain_randomization=True, pool=64, seed=1)
    again.reset()
    np.testing.assert_array_equal(again.points(), first)


def test_torch_arrays_share_the_twins_memory():
    torch = pytest.importorskip("torch")
    tw = twin("halfcheetah", 2, array="torch")
    obs, _ = tw.reset()
    assert isinstance(obs, torch.Tensor) and obs.shape == (2, 17)
    obs, reward, term, trunc, _ = tw.step(torch.zeros(2, 6))
    assert reward.dtype == torch.float32 and term.dtype == torch.bool


def test_refusals_name_the_culprit():
    with pytest.raises(ValueError, match="PGS"):
        WarpTwin("humanoidstandup", 2, device="cpu")
    assert "humanoidstandup" in REFUSED
    with pytest.raises(ValueError, match="tasks with one"):
        WarpTwin("swimmer", 2, device="cpu")
    with pytest.raises(ValueError, match=r"expected \(2, 3\)"):
        twin("hopper", 2, points=np.ones((3, 3)))
    with pytest.raises(ValueError, match="outside"):
        twin("hopper", 1, points=np.array([[100.0, 1.0, 1.0]]))
    with pytest.raises(ValueError, match="array='jax'"):
        twin("hopper", 1, array="jax")
