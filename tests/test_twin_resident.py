"""The twin's device-resident training loop (``rrls.agents.on_twin.train_on_twin``) on warp's CPU
device: nothing crosses to the host inside a block of steps, a run's numbers do not depend on
the block size, the CUDA-graph path (rehearsed) computes what the eager one does, and a
transition is stored as the twin gave it."""

from __future__ import annotations

import numpy as np
import pytest
import torch

pytest.importorskip("warp")
pytest.importorskip("mujoco_warp")

from conftest import HostReads

from rrls.agents.graphs import settings
from rrls.agents.on_twin import train_on_twin

#: the long end-to-end tier (.ci/run runs it after the default suite)
pytestmark = pytest.mark.e2e

STEPS, STARTS = 60, 20
HYPER = {"learning_starts": STARTS, "batch_size": 16, "hidden": (16, 16)}


def _train(algo: str, block: int, **kw):
    return train_on_twin(
        algo,
        "invertedpendulum",
        seeds=(0, 1),
        steps=STEPS,
        device="cpu",
        hyper=HYPER,
        block=block,
        progress_every=STEPS,
        **kw,
    )


@pytest.mark.warp
@pytest.mark.parametrize("algo", ["td3", "dr", "rarl", "nrmdp", "m2td3", "sac", "sacdr"])
def test_the_host_reads_once_a_block_and_the_block_size_changes_nothing(algo, monkeypatch):
    """Every built-in algorithm: no read back inside a block (the CUDA-graph path's static
    inputs rehearsed), and the same runs whatever the block size."""
    whole = _train(algo, block=STEPS)
    reads = HostReads(monkeypatch)
    with settings(rehearse=True):  # the CUDA-graph path's static inputs, without the capture
        blocks = _train(algo, block=7)
    monkeypatch.undo()
    ends = {0, *range(7, STEPS, 7), STEPS}
    inside = sorted(set(reads.at) - ends)
    assert not inside, f"host reads inside a block, at steps {inside}"
    assert any(0 < s < STEPS for s in reads.at)  # the counter sees the block ends' reads
    assert blocks.returns == whole.returns and sum(map(len, whole.returns)) > 0
    obs = np.random.default_rng(0).normal(size=(5, 4))
    for a, b in zip(whole.policies, blocks.policies, strict=True):
        np.testing.assert_array_equal(a(obs), b(obs))
    assert not np.array_equal(whole.policies[0](obs), whole.policies[1](obs))  # two runs


@pytest.mark.warp
def test_a_stored_transition_is_the_twins_step(monkeypatch):
    """The replay's rows are the twin's (obs, action, reward, last obs, terminated), the last
    observation of an ended episode included (not the next episode's first)."""
    from rrls.agents.replay import ReplayBuffer
    from rrls.twin import WarpTwin

    seen, stored = [], []
    step, put = WarpTwin.step, ReplayBuffer.put

    def record_step(twin, actions):
        out = step(twin, actions)
        obs, reward, terminated, truncated, info = out
        ended = (terminated | truncated)[:, None]
        last = torch.where(ended, info["final_obs"], obs)
        seen.append((actions.clone(), reward.clone(), last.clone(), terminated.clone(), ended))
        return out

    def record_put(buffer, **fields):
        stored.append({k: v.clone() for k, v in fields.items()})
        return put(buffer, **fields)

    monkeypatch.setattr(WarpTwin, "step", record_step)
    monkeypatch.setattr(ReplayBuffer, "put", record_put)
    result = _train("td3", block=16)
    assert len(seen) == len(stored) == STEPS and sum(map(len, result.returns)) > 0
    restarts = 0
    for t, ((actions, reward, last, terminated, _), row) in enumerate(zip(seen, stored)):
        torch.testing.assert_close(row["action"], actions.float())
        torch.testing.assert_close(row["reward"], reward)
        torch.testing.assert_close(row["next_obs"], last)
        assert torch.equal(row["terminated"], terminated)
        if t:  # a continuing episode's next state is the following step's state; an ended
            # one's following step starts from the next episode's first state, not its last
            ended = seen[t - 1][4].squeeze(1)
            torch.testing.assert_close(row["obs"][~ended], stored[t - 1]["next_obs"][~ended])
            if ended.any():
                assert not torch.isclose(row["obs"][ended], stored[t - 1]["next_obs"][ended]).all()
            restarts += int(ended.sum())
    assert restarts > 0


def test_bad_blocks_are_refused_in_one_line():
    for name in ("block", "steps", "progress_every"):
        with pytest.raises(ValueError, match=f"{name} must be a positive integer, got 0"):
            train_on_twin("td3", "invertedpendulum", device="cpu", **{name: 0})


@pytest.mark.e2e
@pytest.mark.warp
def test_rrls_train_on_the_twin_reads_back_only_at_checkpoints_and_evaluations(
    tmp_path, monkeypatch
):
    """``rrls train --simulator warp`` for a learner with the device methods: blocks end at
    every checkpoint and periodic evaluation (the host's only reads); a run stopped after a
    checkpoint resumes its episode in progress from that episode's first state and finishes."""
    from rrls.agents import TrainConfig, train
    from rrls.agents.run import read_checkpoint

    def config(name: str) -> TrainConfig:
        return TrainConfig(
            algo="td3",
            task="invertedpendulum",
            seed=3,
            steps=120,
            out=str(tmp_path / name),
            device="cpu",
            simulator="warp",
            checkpoint_every=60,
            eval_every=60,
            eval_episodes=1,
            hyper={"learning_starts": STARTS, "batch_size": 16, "hidden": [16, 16]},
        )

    reads = HostReads(monkeypatch)
    run = train(config("whole"))
    monkeypatch.undo()
    inside = sorted(set(reads.at) - {0, 60, 120})
    assert not inside, f"host reads inside a block, at steps {inside}"
    saved = read_checkpoint(run / "checkpoint.pt")
    assert saved["twin_episode"] >= 2  # InvertedPendulum's random episodes are short
    scalars = (run / "scalars.csv").read_text()
    assert "charts/episode_return" in scalars and "eval/" in scalars
    from rrls.agents.run import STOP_AT_ENV

    monkeypatch.setenv(STOP_AT_ENV, "60")
    from rrls.agents import Interrupted

    with pytest.raises(Interrupted):
        train(config("cut"))
    monkeypatch.delenv(STOP_AT_ENV)
    resumed = train(config("cut"), resume=True)
    import json

    assert json.loads((resumed / "run.json").read_text())["steps"] == 120


@pytest.mark.warp
def test_a_world_restarts_its_episode_and_draws_dr_points_from_its_own_seed():
    from rrls.twin import WarpTwin

    def twin(seeds):
        return WarpTwin("invertedpendulum", len(seeds), domain_randomization=True,
                        seed=seeds, pool_seed=0, device="cpu", array="numpy")  # fmt: skip

    pair, alone = twin([11, 12]), twin([11])
    first, _ = pair.reset()
    np.testing.assert_array_equal(pair.restart(np.array([1, 1])), first)
    rng = np.random.default_rng(0)
    starts, points = [], []
    while len(starts) < 2:  # world 0's second and third episodes begin
        obs, _, term, trunc, _ = pair.step(rng.uniform(-3, 3, (2, 1)).astype(np.float32))
        if term[0] or trunc[0]:
            starts.append((pair.episodes()[0], obs[0].copy()))
            points.append(pair.points()[0])
    counts = pair.episodes()
    counts[0] = starts[0][0]
    np.testing.assert_array_equal(pair.restart(counts)[0], starts[0][1])
    alone.reset()
    for (count, _), point in zip(starts, points):  # the same point without world 1 beside it
        alone.restart(np.array([count]))
        np.testing.assert_array_equal(alone.points()[0], point)
    pair.close()
    alone.close()


def test_a_non_finite_action_stops_training_at_its_step_naming_the_seed():
    from rrls.agents import Diverged
    from rrls.agents.resident import Block, check_finite, ended

    bad = torch.zeros((4, 2), dtype=torch.bool)
    returns = torch.full((4, 2), float("nan"), dtype=torch.float64)
    returns[1, 0], returns[3, 1] = 12.5, 7.0
    lengths = torch.zeros((4, 2), dtype=torch.int64)
    lengths[1, 0], lengths[3, 1] = 30, 44
    block = Block(returns, lengths, bad, {})
    check_finite(block, 100, [5, 6], "td3")  # all finite: nothing raised
    assert ended(block) == [(1, 0, 12.5, 30), (3, 1, 7.0, 44)]
    bad[2, 1] = bad[3, 0] = True
    with pytest.raises(Diverged, match=r"^training stopped at step 103: td3 .* seed 6;"):
        check_finite(block, 100, [5, 6], "td3")


def test_the_docs_state_the_block_the_code_uses():
    from pathlib import Path

    from rrls.agents.resident import BLOCK

    twin = " ".join((Path(__file__).parents[1] / "docs" / "twin.md").read_text().split())
    assert f"once per block of {BLOCK} steps" in twin and f"(`block={BLOCK}`)" in twin


@pytest.mark.warp
@pytest.mark.e2e
def test_rrls_train_on_the_twin_writes_the_same_run_whatever_the_block(tmp_path, monkeypatch):
    """The driver's run files (curves, checkpoint, policy) of ``rrls train --simulator warp`` do
    not depend on how many steps a block runs between the host's looks."""
    from conftest import policy_arrays

    from rrls.agents import TrainConfig, resident, train
    from rrls.agents.run import read_checkpoint

    def run(block: int):
        monkeypatch.setattr(resident, "BLOCK", block)
        return train(
            TrainConfig(
                algo="sac",
                task="invertedpendulum",
                seed=4,
                steps=100,
                out=str(tmp_path / f"block{block}"),
                device="cpu",
                simulator="warp",
                checkpoint_every=45,  # at 45 and 90: inside blocks of 64, at block ends of 5
                eval_every=70,
                eval_episodes=1,
                hyper={"learning_starts": STARTS, "batch_size": 16, "hidden": [16, 16]},
            )
        )

    def curves(path):
        rows = (path / "scalars.csv").read_text().splitlines()
        return [r for r in rows if ",charts/steps_per_second," not in r]

    whole, blocks = run(resident.BLOCK), run(5)
    assert curves(whole) == curves(blocks) and any(",eval/" in r for r in curves(whole))
    a, b = policy_arrays(whole), policy_arrays(blocks)
    assert a.keys() == b.keys() and all(np.array_equal(a[k], b[k]) for k in a)
    saved = [read_checkpoint(p / "checkpoint.pt") for p in (whole, blocks)]
    assert saved[0]["step"] == saved[1]["step"] == 90
    assert saved[0]["twin_episode"] == saved[1]["twin_episode"]
    _same(saved[0]["learner"], saved[1]["learner"])


def _same(a, b) -> None:
    """Equal nested checkpoint contents, tensors bit for bit."""
    if isinstance(a, dict):
        assert a.keys() == b.keys()
        for key in a:
            _same(a[key], b[key])
    elif isinstance(a, (list, tuple)):
        assert len(a) == len(b)
        for x, y in zip(a, b):
            _same(x, y)
    elif isinstance(a, torch.Tensor):
        assert torch.equal(a, b)
    else:
        assert a == b


@pytest.mark.warp
@pytest.mark.exactness  # batched updates: .ci/run repeats it on the other CPU kernels
@pytest.mark.parametrize("algo", ["td3", "dr", "rarl", "nrmdp", "m2td3", "sac", "sacdr"])
def test_a_twin_run_is_the_same_alone_and_beside_another(algo):
    """A run's numbers do not depend on what else shares its twin: seed 1 trained alone and
    trained beside seed 0 (its world and its learner's slice of the stacked update) give the
    same episodes and the same policy."""

    def train(seeds: tuple[int, ...]):
        return train_on_twin(
            algo,
            "invertedpendulum",
            seeds=seeds,
            steps=STEPS,
            device="cpu",
            hyper=HYPER,
            block=16,
            progress_every=STEPS,
        )

    alone, shared = train((1,)), train((0, 1))
    assert alone.returns[0] == shared.returns[1] and alone.returns[0]
    obs = np.random.default_rng(0).normal(size=(5, 4))
    np.testing.assert_array_equal(alone.policies[0](obs), shared.policies[1](obs))
