"""The adversarial baselines on the MuJoCo Warp twin, on warp's CPU device: NR-MDP's and RARL's
device-resident methods compute what their CPU paths compute (the same updates on the same
draws, the same actions on the same noise), the twin writes RARL's forces per world as the CPU
game does and follows CPU MuJoCo within the twin's tolerances (``docs/twin.md``: 1e-5 in qpos
after one step, 1e-4 after ten, rewards within 1e-3, terminations equal), and a block of steps
reads nothing back before its end."""

from __future__ import annotations

import json

import numpy as np
import pytest
import torch
from conftest import HostReads, assert_worlds_follow_cpu

from rrls.agents.algos import nrmdp, rarl
from rrls.agents.streams import RunSeeds

#: the long end-to-end tier (.ci/run runs it after the default suite)
pytestmark = pytest.mark.e2e

SMALL = {"learning_starts": 20, "batch_size": 16, "hidden": (16, 16), "policy_frequency": 1}
SEEDS = [RunSeeds(0), RunSeeds(1)]
CPU = torch.device("cpu")


def _nrmdp(**kw) -> tuple[nrmdp.Learner, nrmdp.Config]:
    config = nrmdp.Config(**{**SMALL, "ratio": 1, **kw})
    env = nrmdp.make_env("invertedpendulum", None, config)
    return nrmdp.Learner(env, config, SEEDS, CPU), config


def _rarl(**kw) -> rarl.Learner:
    config = rarl.Config(**{**SMALL, **kw})
    return rarl.Learner(rarl.make_env("invertedpendulum", "rarl", config), config, SEEDS, CPU)


def _fill(buffers, rows: int, seed: int = 0) -> None:
    """The same random transitions into every buffer of ``buffers`` (one list per learner)."""
    rng = np.random.default_rng(seed)
    for _ in range(rows):
        fields = {}
        for name, shape in buffers[0].shapes.items():
            value = rng.normal(size=(2, *shape)).astype(np.float32)
            fields[name] = (value > 0).astype(np.float32) if name == "terminated" else value
        for buffer in buffers:
            buffer.put(**{k: torch.from_numpy(v) for k, v in fields.items()})


def _same_state(a, b) -> None:
    for x, y in zip(_tensors(a.state_dict()), _tensors(b.state_dict()), strict=True):
        assert torch.equal(x, y)


def _tensors(state):
    if isinstance(state, torch.Tensor):
        yield state
    elif isinstance(state, dict):
        for v in state.values():
            yield from _tensors(v)
    elif isinstance(state, list | tuple):
        for v in state:
            yield from _tensors(v)


# -- NR-MDP ---------------------------------------------------------------------------------
@pytest.mark.parametrize("mode", ["nr", "pr"])
def test_nrmdp_update_drawn_is_update_on_the_same_draws(mode):
    """Both turns (ratio 1: adversary and protagonist alternate), the critic at every step."""
    (cpu, config), (dev, _) = _nrmdp(mode=mode), _nrmdp(mode=mode)
    _fill([cpu.buffer, dev.buffer], 40)
    size, turns = config.batch_size, set()
    for step in range(1, 7):
        lost = cpu.update(step)
        draws = {"idx": dev.buffer.draw(size)}
        draws.update({"mine": dev.agent.draw(size), "theirs": dev.agent.draw(size)})
        got = dev.update_drawn(step, draws)
        assert lost.keys() == got.keys()
        turns |= set(lost)
        for name in lost:
            assert torch.equal(lost[name], got[name])
    assert {"adversary_loss", "actor_loss"} <= turns
    _same_state(cpu, dev)


@pytest.mark.parametrize("mode", ["nr", "pr"])
def test_nrmdp_acts_on_the_device_as_the_env_executes(mode):
    """``act_tensor`` is the action ``ProbabilisticActionRobust`` executes for ``act``'s pair,
    with the exploration noise of the same stream; PR-MDP's coin picks the adversary's."""
    (cpu, config), (dev, _) = _nrmdp(mode=mode, alpha=0.5), _nrmdp(mode=mode, alpha=0.5)
    obs = np.random.default_rng(1).normal(size=(2, 4)).astype(np.float32)
    draws = dev.draw_ahead(3)
    coins = draws.get("coin")
    for t in range(3):
        pairs = cpu.act(obs)
        mine, theirs = (np.stack(p) for p in zip(*pairs))
        got = dev.act_tensor(torch.from_numpy(obs), {k: v[t] for k, v in draws.items()}).numpy()
        if mode == "nr":
            want = (1.0 - config.alpha) * mine + config.alpha * theirs
        else:
            want = np.where(coins[t].numpy()[:, None], theirs, mine)
        np.testing.assert_allclose(got, want, atol=1e-6)
    if coins is not None:  # both sides of the coin were drawn
        assert coins.any() and not coins.all()


def test_nrmdp_normalises_on_the_device_as_on_the_host():
    """``normalize_obs``: the device's statistics follow every stored state as the host's do
    (Tessler's pooled update, in float64), and both players act on the normalised state."""
    (cpu, config), (dev, _) = _nrmdp(normalize_obs=True), _nrmdp(normalize_obs=True)
    rng = np.random.default_rng(3)
    draws = dev.draw_ahead(5)
    for t in range(5):
        obs, after = (rng.normal(1.0, 2.0, size=(2, 4)).astype(np.float32) for _ in range(2))
        mine, theirs = (np.stack(p) for p in zip(*cpu.act(obs)))
        executed = ((1.0 - config.alpha) * mine + config.alpha * theirs).astype(np.float32)
        got = dev.act_tensor(torch.from_numpy(obs), {k: v[t] for k, v in draws.items()})
        np.testing.assert_allclose(got.numpy(), executed, atol=1e-6)
        reward, done = np.array([1.0, -1.0]), np.zeros(2)
        cpu.observe(obs, None, reward, after, done, [{"executed_action": a} for a in executed])
        dev.put(*(torch.from_numpy(x) for x in (obs, executed, reward, after, done)))
    for name in ("mean", "var", "count"):
        np.testing.assert_allclose(
            dev.stats.state_dict()[name], cpu.stats.state_dict()[name], rtol=1e-12
        )
    assert dev.stats.std32[0, 0] > 1.5  # the stats moved
    assert torch.equal(cpu.buffer.table[:, :5], dev.buffer.table[:, :5])


# -- RARL -----------------------------------------------------------------------------------
@pytest.mark.parametrize("schedule", ["simultaneous", "alternating"])
def test_rarl_update_drawn_is_update_on_the_same_draws(schedule):
    cpu, dev = _rarl(schedule=schedule, phase_steps=2), _rarl(schedule=schedule, phase_steps=2)
    _fill(cpu.buffers[:1] + dev.buffers[:1], 40, seed=0)
    _fill(cpu.buffers[1:] + dev.buffers[1:], 40, seed=1)
    size, names = cpu.config.batch_size, set()
    for step in range(21, 27):
        lost = cpu.update(step)
        draws = {}
        for i in (0, 1):  # what update draws: the learning players' rows, the protagonist first
            if i in dev.learning(step):
                draws[f"idx{i}"] = dev.buffers[i].draw(size)
                draws[f"eps{i}"] = dev.players[i].draw(size)
        got = dev.update_drawn(step, draws)
        assert lost.keys() == got.keys()
        names |= set(lost)
        for name in lost:
            assert torch.equal(lost[name], got[name])
    assert {"protagonist_actor_loss", "adversary_actor_loss"} <= names
    _same_state(cpu, dev)


def test_rarl_acts_and_stores_on_the_device_as_on_the_cpu():
    """The joint action is ``act``'s pair, the protagonist's columns first; ``put`` stores each
    player's columns, the adversary's transition with ``-reward``."""
    cpu, dev = _rarl(), _rarl()
    rng = np.random.default_rng(2)
    obs, next_obs = (rng.normal(size=(2, 4)).astype(np.float32) for _ in range(2))
    reward, terminated = np.array([1.5, -0.5]), np.array([0.0, 1.0])
    draws = dev.draw_ahead(1)
    pairs = cpu.act(obs)
    joint = dev.act_tensor(torch.from_numpy(obs), {k: v[0] for k, v in draws.items()})
    want = np.concatenate([np.stack(p) for p in zip(*pairs)], 1)
    np.testing.assert_allclose(joint.numpy(), want, atol=1e-6)
    cpu.observe(obs, pairs, reward, next_obs, terminated, [{}, {}])
    dev.put(*(torch.from_numpy(x) for x in (obs, want, reward, next_obs, terminated)))
    for a, b in zip(cpu.buffers, dev.buffers, strict=True):
        assert torch.equal(a.table[:, 0], b.table[:, 0])


def test_rarl_refuses_tc_rmdp_on_the_device():
    with pytest.raises(ValueError, match="TC-RMDP"):
        _rarl(rate_limit=0.001).draw_ahead(1)


# -- on the twin ----------------------------------------------------------------------------
pytest.importorskip("warp")
pytest.importorskip("mujoco_warp")


@pytest.mark.warp
@pytest.mark.parametrize("uncertainty", ["rarl", "3d"])
def test_each_world_takes_its_adversarys_point_as_the_cpu_game_does(uncertainty):
    """Per world, the forces written are the CPU game's values (bit for bit in float32), the
    masses and friction its model's (derived constants within float32), and the state follows a
    CPU ``DynamicAdversarial`` from the same state within the twin's stated tolerances, the
    adversary's actions out of ``[-1, 1]`` included (clipped as on the CPU)."""
    from rrls.envs import resolve
    from rrls.twin import WarpTwin
    from rrls.wrappers import DynamicAdversarial

    worlds, resolved = 3, resolve("hopper", uncertainty)
    twin = WarpTwin("hopper", worlds, uncertainty, adversary=True, device="cpu", seed=0)
    twin.reset()
    qpos, qvel = twin.state()
    games = []
    for w in range(worlds):
        game = DynamicAdversarial(resolved.make_env(), resolved.box)
        game.reset(seed=0)
        game.unwrapped.set_state(qpos[w].astype(np.float64), qvel[w].astype(np.float64))
        games.append(game)
    space, rng = twin.single_action_space, np.random.default_rng(0)
    nu = space.shape[0] - twin.adversary_dim
    seen = []
    for t in range(10):
        action = rng.uniform(1.3 * space.low, 1.3 * space.high, (worlds, space.shape[0]))
        action = action.astype(np.float32)
        _, reward, terminated, _, _ = twin.step(action)
        forces, (tq, tv) = twin.d.xfrc_applied.numpy().reshape(worlds, -1), twin.state()
        mass, subtree = twin.m.body_mass.numpy(), twin.m.body_subtreemass.numpy()
        for w, game in enumerate(games):
            _, r, term, _, _ = game.step((action[w, :nu].astype(np.float64), action[w, nu:]))
            model, data = game.unwrapped.model, game.unwrapped.data
            np.testing.assert_array_equal(forces[w], np.float32(data.xfrc_applied).ravel())
            np.testing.assert_array_equal(mass[w], np.float32(model.body_mass))
            np.testing.assert_allclose(subtree[w], model.body_subtreemass, rtol=1e-6)
            seen.append(game.get_params())
            assert bool(term) == bool(terminated[w])
            tol = 1e-5 if t == 0 else 1e-4
            assert np.abs(tq[w] - data.qpos).max() < tol
            assert np.abs(tv[w] - data.qvel).max() < 100 * tol
            assert abs(float(reward[w]) - r) < 1e-3
    box = resolved.box  # the box's edges reached, from clipped actions
    for name, lo, hi in zip(box.names, box.low, box.high):
        values = [float(p[name]) for p in seen]
        assert np.isclose(min(values), lo) and np.isclose(max(values), hi)


@pytest.mark.warp
def test_dr_draws_a_point_of_the_box_per_episode_and_world_on_the_device():
    """``pool=0``: each episode's point is a uniform draw of the whole box from the world's own
    stream (the same whatever the group, again on a restart of that episode), its fields
    written on the device; each world follows a CPU env at its point within the tolerances."""
    from rrls.envs import resolve
    from rrls.twin import WarpTwin

    resolved = resolve("hopper", "3d")
    box = resolved.box
    fresh = {"domain_randomization": True, "pool": 0, "device": "cpu"}
    twin = WarpTwin("hopper", 3, "3d", seed=[5, 6, 7], **fresh)
    alone = WarpTwin("hopper", 1, "3d", seed=[7], **fresh)
    for t in (twin, alone):
        t.reset()
    first = twin.points()
    assert np.array_equal(alone.points()[0], first[2])  # world 2's draw is its seed's alone
    assert all(box.contains(p) for p in first) and len({tuple(p) for p in first}) == 3
    assert_worlds_follow_cpu(twin, resolved, first)
    twin.restart(np.array([2, 2, 2]))
    second = twin.points()
    assert all(box.contains(p) for p in second) and not np.isin(second, first).any()
    twin.restart(np.array([1, 1, 1]))
    np.testing.assert_array_equal(twin.points(), first)


def test_an_adversary_with_points_is_refused():
    from rrls.twin import WarpTwin

    with pytest.raises(ValueError, match="no points or DR"):
        WarpTwin("invertedpendulum", 1, "rarl", adversary=True, domain_randomization=True)


STEPS = 40


def _rarl_blocks(block: int, uncertainty: str) -> tuple[list, rarl.Learner]:
    """RARL's game for two runs on the twin, through the resident loop's blocks
    (``rrls.agents.resident.Worlds``): what the training loops run once they build the twin
    with ``adversary=True``."""
    from rrls.agents.resident import Worlds, ended, make_part
    from rrls.twin import WarpTwin

    config = rarl.Config(**SMALL)
    game = rarl.make_env("invertedpendulum", uncertainty, config)
    learner = rarl.Learner(game, config, SEEDS, CPU)
    seeds = [s.integer("env") for s in SEEDS]
    twin = WarpTwin(
        "invertedpendulum", 2, uncertainty, adversary=True, seed=seeds, device="cpu", array="torch"
    )
    worlds = Worlds(twin, CPU)
    part = make_part(twin, learner, [s.seed for s in SEEDS], SMALL["learning_starts"], "rarl")
    worlds.start()
    out, done = [], 0
    while done < STEPS:
        n = min(block, STEPS - done)
        out += ended(worlds.block([part], done, n)[0])
        done += n
    twin.close()
    return [(done_at, w, r) for done_at, w, r, _ in out], learner


@pytest.mark.warp
@pytest.mark.parametrize("uncertainty", ["rarl", "2d"])
def test_rarl_on_the_twin_reads_once_a_block_and_the_block_size_changes_nothing(
    uncertainty, monkeypatch
):
    """Forces, or masses whose derived constants ``set_const`` recomputes, at every step."""
    whole, a = _rarl_blocks(STEPS, uncertainty)
    reads = HostReads(monkeypatch)
    blocks, b = _rarl_blocks(7, uncertainty)
    monkeypatch.undo()
    inside = sorted(set(reads.at) - {0, *range(7, STEPS, 7), STEPS})
    assert not inside, f"host reads inside a block, at steps {inside}"
    assert sorted(r for *_, r in blocks) == sorted(r for *_, r in whole) and whole
    _same_state(a, b)
    assert b.buffers[1].size == STEPS  # the adversary stored every step


@pytest.mark.e2e  # whole twin trainings: the long tier
@pytest.mark.warp
def test_nrmdp_trains_on_the_twin_reading_once_a_block(monkeypatch):
    """The library's twin loop (``train_on_twin``) trains NR-MDP (its statistics on the
    device too), both players' policy steps taken; a run's numbers do not depend on the block
    size."""
    from rrls.agents.on_twin import train_on_twin

    def train(block: int, mode: str = "nr", steps: int = STEPS):
        hyper = {**SMALL, "ratio": 1, "mode": mode, "alpha": 0.3, "normalize_obs": mode == "nr"}
        return train_on_twin(
            "nrmdp",
            "invertedpendulum",
            seeds=(0, 1),
            steps=steps,
            device="cpu",
            hyper=hyper,
            block=block,
            progress_every=steps,
        )

    whole = train(STEPS)
    reads = HostReads(monkeypatch)
    blocks = train(7)
    monkeypatch.undo()
    inside = sorted(set(reads.at) - {0, *range(7, STEPS, 7), STEPS})
    assert not inside, f"host reads inside a block, at steps {inside}"
    assert blocks.returns == whole.returns and sum(map(len, whole.returns)) > 0
    obs = np.random.default_rng(0).normal(size=(5, 4))
    for x, y in zip(whole.policies, blocks.policies, strict=True):
        np.testing.assert_array_equal(x(obs), y(obs))
    longer = train(64, mode="pr", steps=200)  # a few hundred steps, PR-MDP's coin on the device
    assert all(len(r) > 1 for r in longer.returns)


@pytest.mark.e2e  # whole twin trainings: the long tier
@pytest.mark.warp
def test_rarl_trains_through_both_twin_paths_and_its_other_games_are_refused(tmp_path):
    """``train_on_twin`` and ``rrls train --simulator warp`` build RARL's twin with the
    adversary (``resident.make_twin``): both players learn, the block size changes nothing; the
    game the twin does not play (TC-RMDP's rate-limited adversary) is one
    line before a twin is built."""
    from rrls.agents.on_twin import train_on_twin
    from rrls.cli.app import main

    def train(block: int):
        return train_on_twin(
            "rarl", "hopper", seeds=(0, 1), steps=STEPS, device="cpu", hyper=SMALL, block=block,
            uncertainty="rarl", progress_every=STEPS,
        )  # fmt: skip

    whole, blocks = train(STEPS), train(7)
    assert blocks.returns == whole.returns and sum(map(len, whole.returns)) > 0
    obs = np.random.default_rng(0).normal(size=(5, 11))
    for x, y in zip(whole.policies, blocks.policies, strict=True):
        np.testing.assert_array_equal(x(obs), y(obs))
    with pytest.raises(ValueError, match="with --rate-limit .* trains on CPU MuJoCo"):
        hyper = {**SMALL, "rate_limit": 0.1}  # TC-RMDP, its observation variants with it
        train_on_twin("rarl", "hopper", seeds=(0,), steps=5, device="cpu", hyper=hyper)
    out = tmp_path / "rarl"
    argv = ["train", "--algo", "rarl", "--task", "hopper", "--simulator", "warp", "--device"]
    argv += ["cpu", "--steps", "40", "--learning-starts", "20", "--batch-size", "16"]
    argv += ["--hidden", "16", "16", "--eval-every", "40", "--eval-episodes", "1"]
    argv += ["--eval-mesh", "1", "--out", str(out)]
    assert main(argv) == 0
    run = json.loads((out / "run.json").read_text())
    assert run["algorithm"] == "rarl" and run.get("simulator", "warp") == "warp"
    assert (out / "policy.npz").is_file()
