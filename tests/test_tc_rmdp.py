"""TC-RMDP's game as its authors play it (SuReLI/TCRMDP ``src/tc_mdp.py``): moves in raw units,
uniform starts, the adversary observing ψ, the Vanilla/Stacked/Oracle protagonists."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from rrls.envs import HopperParamsBound, RobustHopper, RobustInvertedPendulum
from rrls.evaluation import MLPPolicy, evaluate
from rrls.uncertainty import UncertaintySet
from rrls.wrappers import DynamicAdversarial, ProtagonistObservation, View
from rrls.wrappers.tc_rmdp import unit_psi

BOX = UncertaintySet.from_bounds(HopperParamsBound.THREE_DIM.value)


def _game(radius: float = 0.1, **kw) -> DynamicAdversarial:
    return DynamicAdversarial(RobustHopper(), BOX, rate_limit=radius, **kw)


@pytest.mark.parametrize("radius", [0.0, 0.001, 0.1, 0.7])
def test_a_random_adversarys_moves_obey_the_bound_in_raw_units(radius):
    game, rng = _game(radius), np.random.default_rng(0)
    _, info = game.reset(seed=0)
    psi, largest = info["psi"], np.zeros(3)
    for t in range(300):
        a = rng.uniform(-1, 1, 3).astype(np.float32)
        *_, term, trunc, info = game.step((np.zeros(3), a))
        # the authors' move (tc_mdp.py:145-148), per coordinate in raw parameter units
        expected = np.clip(psi + a.astype(np.float64) * radius, BOX.low, BOX.high)
        assert np.array_equal(info["psi"], expected), t
        step = np.abs(info["psi"] - psi)
        assert np.all(step <= radius * (1 + 1e-12)), (t, step)
        assert BOX.contains(info["psi"])
        now = game.get_params()
        assert [now[n] for n in BOX.names] == info["psi"].tolist()  # what the physics holds
        largest, psi = np.maximum(largest, step), info["psi"]
        if term or trunc:
            game.reset()
            psi = game.get_params()
            psi = np.array([psi[n] for n in BOX.names])
    if radius:  # the bound is the move's own size: every axis gets close to it
        assert np.all(largest > 0.9 * radius), largest


def test_the_bound_is_raw_not_normalised():
    # worked example of the docs: friction (0.1, 3.1) from 1.0, a = +1, radius 0.1: 1.1, while
    # rrls's earlier game moved 0.1 of the normalised [-1, 1] axis, 0.15 in raw units
    bounds = {"worldfriction": (0.1, 3.1)}
    tc = DynamicAdversarial(RobustHopper(), bounds, rate_limit=0.1)
    tc.reset(seed=0, options={"worldfriction": 1.0})
    *_, info = tc.step((np.zeros(3), np.array([1.0], np.float32)))
    assert info["psi"].tolist() == [1.1] and tc.get_params()["worldfriction"] == 1.1
    *_, info = tc.step((np.zeros(3), np.array([-0.5], np.float32)))
    assert info["psi"][0] == pytest.approx(1.05, abs=1e-15)
    old = DynamicAdversarial(RobustHopper(), bounds, rate_limit=0.1, rate_game="target")
    old.reset(seed=0)
    *_, info = old.step((np.zeros(3), np.array([1.0], np.float32)))
    assert round(info["worldfriction"], 6) == 1.15


def test_starts_are_uniform_in_the_box():
    game = _game()
    starts = [game.reset(seed=123)[1]["psi"]]
    starts += [game.reset()[1]["psi"] for _ in range(799)]  # the seeded stream goes on
    unit = unit_psi(BOX, np.array(starts))
    assert np.all((unit >= 0) & (unit <= 1))
    for axis in range(3):  # each coordinate uniform on its interval (KS, fixed seed)
        assert stats.kstest(unit[:, axis], "uniform").pvalue > 0.01, axis
    assert abs(np.corrcoef(unit.T)[0, 1]) < 0.1  # drawn independently
    # not rrls's earlier start (nominal clipped into the box: Hopper's upper corner)
    assert np.mean(np.all(np.isclose(unit, 1.0), axis=1)) < 0.01


def test_reset_options_fix_a_start_and_bad_ones_change_nothing():
    game = _game()
    _, info = game.reset(seed=5, options={"torsomass": 2.0})  # axes: friction, torso, thigh
    assert info["psi"][1] == 2.0 and game.get_params()["torsomass"] == 2.0
    drawn = game.reset(seed=5)[1]["psi"]
    assert drawn[[0, 2]].tolist() == info["psi"][[0, 2]].tolist()  # the others: the same draw
    state = game.np_random.bit_generator.state
    with pytest.raises(ValueError, match=r"torsomass=9.0 must be a number in the game's box"):
        game.reset(options={"torsomass": 9.0})
    assert game.np_random.bit_generator.state == state


def test_observations_carry_psi_and_the_state():
    game = _game(0.2)
    (p0, p1), (a0, a1) = game.views
    assert (p0, p1, a0, a1) == (0, 11, 11, 25) and game.observation_space.shape == (25,)
    obs, info = game.reset(seed=1)
    for t in range(20):
        s = game.unwrapped._get_obs()
        assert np.array_equal(obs[p0:p1], s)  # Vanilla: the state
        # the adversary's [ψ01, s], ψ normalised as the authors do (tc_mdp.py:589-596)
        assert np.array_equal(obs[a0 : a0 + 3], (info["psi"] - BOX.low) / (BOX.high - BOX.low))
        assert np.array_equal(obs[a0 + 3 : a1], s)
        obs, *_, info = game.step((np.zeros(3), np.full(3, 1.0 if t % 2 else -1.0)))


def test_the_stacked_and_oracle_protagonists_see_what_the_paper_says():
    stacked = _game(0.2, observe="stacked")
    assert stacked.views == ((0, 25), (25, 39))  # [s', s, a'] then [ψ01, s]
    obs, _ = stacked.reset(seed=2)
    s0 = stacked.unwrapped._get_obs()
    assert np.array_equal(obs[:25], np.concatenate([s0, s0, np.zeros(3)]))  # tc_mdp.py:597-599
    act = np.array([0.1, -0.2, 0.3], np.float32)
    obs, *_ = stacked.step((act, np.zeros(3)))
    s1 = stacked.unwrapped._get_obs()
    assert np.array_equal(obs[:25], np.concatenate([s0, s1, act.astype(np.float64)]))
    deep = _game(0.2, observe="stacked", history=3)
    assert deep.views[0] == (0, 4 * 11 + 3 * 3)
    oracle = _game(0.2, observe="oracle")
    obs, info = oracle.reset(seed=2)
    assert oracle.views == ((0, 14), (14, 28))
    assert np.array_equal(obs[11:14], unit_psi(BOX, info["psi"]))  # [s, ψ01], tc_mdp.py:370
    with pytest.raises(ValueError, match="observe must be one of vanilla, stacked, oracle"):
        _game(observe="psychic")
    with pytest.raises(ValueError, match="history must be an integer >= 1"):
        _game(observe="stacked", history=0)


@pytest.mark.parametrize("observe", ["vanilla", "stacked", "oracle"])
def test_same_seed_same_trajectory(observe):
    def play(seed: int) -> list[np.ndarray]:
        game, rng = _game(0.05, observe=observe), np.random.default_rng(9)
        obs, info = game.reset(seed=seed)
        out = [obs, info["psi"]]
        for _ in range(60):
            pair = (rng.uniform(-1, 1, 3), rng.uniform(-1, 1, 3))
            obs, reward, term, trunc, info = game.step(pair)
            out += [obs, info["psi"], np.array([reward])]
            if term:
                obs, info = game.reset()
                out += [obs, info["psi"]]
        return out

    first, again, other = play(7), play(7), play(8)
    assert all(np.array_equal(x, y) for x, y in zip(first, again, strict=True))
    assert not np.array_equal(first[1], other[1])  # another seed, another start


def test_a_stacked_or_oracle_protagonist_is_evaluated_on_what_it_saw():
    box = UncertaintySet.from_bounds({"polemass": (1.0, 3.0)})
    env = ProtagonistObservation(RobustInvertedPendulum(polemass=2.0), View("oracle", box=box))
    obs, _ = env.reset(seed=0)
    assert obs.shape == (5,) and obs[-1] == 0.5  # static ψ, as EvalStaticOracle
    for view, dim in [(View("stacked"), 9), (View("oracle", box=box), 5)]:
        policy = MLPPolicy.random(dim, 1, hidden=(8,), seed=0)
        policy.metadata = {"task": "invertedpendulum", **view.to_metadata()}
        assert View.from_metadata(policy.metadata) == view
        result = evaluate(policy, "invertedpendulum", box, mesh=2, episodes=1, workers=1)
        assert result.config["protagonist_view"] == view.to_metadata()
        assert len(result.episodes) == 2


def test_the_worked_example_of_the_docs():
    # perturbations.md, differences.md: Hopper 3D, R = 0.1, ψ = (1.0, 2.0, 3.95), a = (1, -0.5, 1)
    game = _game(0.1)
    start = {"worldfriction": 1.0, "torsomass": 2.0, "thighmass": 3.95}
    game.reset(seed=0, options=start)
    obs, *_, info = game.step((np.zeros(3), np.array([1.0, -0.5, 1.0], np.float32)))
    np.testing.assert_allclose(info["psi"], [1.1, 1.95, 4.0], rtol=0, atol=1e-12)
    assert info["psi"][2] == 4.0  # clipped at the bound
    np.testing.assert_allclose(obs[11:14], [0.345, 0.638, 1.0], atol=5e-4)
    old = np.array([0.1, 0.1, 0.1]) * (BOX.high - BOX.low) / 2  # the earlier game's move
    np.testing.assert_allclose(old, [0.145, 0.145, 0.195])


def test_aliases_play_through_their_parameter():
    from rrls.envs import ForceHopper

    game = DynamicAdversarial(ForceHopper(), {"torsoforce_z": (-2.0, 2.0)}, rate_limit=0.5)
    _, info = game.reset(seed=0)
    assert game.unwrapped.get_params()["torsoforce_y"] == info["psi"][0]
    *_, info = game.step((np.zeros(3), np.ones(1)))
    assert game.unwrapped.get_params()["torsoforce_y"] == info["psi"][0]
