"""M2TD3 on the Warp twin without leaving the device: its per-episode rules (restart the
collapsed and rare candidates, draw one, perturb it) and its candidates' Adam step run for all
runs at once, masked, with no host read (``Candidates.restart_masked``, ``select_drawn``,
``step_masked``: the same numbers as the per-run host methods on the same draws), each episode's
point written into its world (``WarpTwin(chosen=True).set_points``: a world at a chosen point
follows the CPU env at that point within the twin's tolerances), and a run's numbers do not
depend on the block size."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from conftest import HostReads, assert_worlds_follow_cpu

from rrls.agents.algos import m2td3
from rrls.agents.streams import NumpyGenerators, RunSeeds

SMALL = {"learning_starts": 20, "batch_size": 16, "hidden": (16, 16), "policy_frequency": 1}


class Constant:
    """A generator whose every uniform draw is ``low + u (high - low)``."""

    def __init__(self, u: float) -> None:
        self.u = u

    def uniform(self, low, high):
        return np.asarray(low) + self.u * (np.asarray(high) - np.asarray(low))


def _candidates(n: int = 4) -> m2td3.Candidates:
    config = m2td3.Config(hatomega_number=n)
    rngs = NumpyGenerators([RunSeeds(3), RunSeeds(4), RunSeeds(5)], "algo")
    return m2td3.Candidates([0.5, 1.0], [2.5, 4.0], rngs, config, torch.device("cpu"))


def _collapse(c: m2td3.Candidates) -> None:
    """Run 0's candidates 1 and 3 onto candidate 0; run 2's candidate 2 rare."""
    with torch.no_grad():
        for j in (1, 3):
            c.logits[j].copy_(c.logits[0] + 0.001)
        c.probabilities[2] = torch.tensor([0.4, 0.35, 0.01, 0.24], dtype=torch.float64)


def _same(a: dict, b: dict) -> None:
    for key in a:
        torch.testing.assert_close(a[key], b[key], msg=key)  # (fused Adam: kernels may differ)


def test_the_masked_restart_is_the_per_run_restart():
    host, device = _candidates(), _candidates()
    _collapse(host)
    _collapse(device)
    device.to_storage()
    before = host.state_dict()["logits"]
    u = [0.25, 0.5, 0.75]
    for k in (0, 2):  # run 1's episode goes on: nothing of it changes
        host.restart(k, Constant(u[k]))
    draws = torch.tensor(u, dtype=torch.float32)[:, None, None].expand(3, 4, 2)
    device.restart_masked(torch.tensor([True, False, True]), draws, draws)
    _same(host.state_dict(), device.state_dict())
    after = host.state_dict()["logits"]
    assert torch.equal(after[1], before[1])  # run 1's episode went on
    assert not torch.equal(after[0], before[0]) and not torch.equal(after[2], before[2])
    assert host.state_dict()["probabilities"][2, 2] > 0.2  # the rare one, restarted


def test_the_drawn_selection_is_numpys_choice_and_the_masked_step_the_per_run_step():
    host, device = _candidates(), _candidates()
    device.to_storage()
    with torch.no_grad():  # uneven probabilities, not normalised (as after a restart)
        for c in (host, device):
            c.probabilities.copy_(torch.tensor([[1, 2, 3, 4], [4, 3, 2, 1], [1, 1, 5, 1.0]]))
    picks = [np.random.default_rng(10 + k) for k in range(3)]
    chosen = [host.select(k, picks[k]) for k in range(3)]
    u = torch.tensor([np.random.default_rng(10 + k).random() for k in range(3)])
    drawn = device.select_drawn(torch.ones(3, dtype=torch.bool), u)
    assert drawn.tolist() == chosen
    for step in range(3):  # Adam's state builds up over steps: the skipped ones stay as they were
        which = torch.tensor([(step + k) % 4 for k in range(3)])
        for c, descend in ((host, host.step), (device, device.step_masked)):
            index = which.view(-1, 1, 1).expand(-1, 1, 2)
            loss = (c.values().gather(1, index) ** 2).sum((1, 2))
            descend(loss, which)
    _same(host.state_dict(), device.state_dict())


def test_same_start_keeps_m2td3_on_each_runs_cpu_env():
    from rrls.agents.config import TrainConfig
    from rrls.agents.resident import trains_on_device

    config = TrainConfig(algo="m2td3", task="invertedpendulum", simulator="warp")
    assert trains_on_device(config, m2td3.Learner, m2td3.Config())
    assert not trains_on_device(config, m2td3.Learner, m2td3.Config(same_start=True))


@pytest.mark.warp
def test_a_world_at_a_chosen_point_follows_the_cpu_env_at_that_point():
    """``set_points``: each world's fields at its point (the derived constants recomputed), a
    world that resets keeps its point, and each follows a CPU env at its point."""
    from rrls.envs import resolve
    from rrls.twin import WarpTwin

    resolved = resolve("hopper", "3d")
    box = resolved.box
    points = np.array([box.low, box.high, np.add(box.low, box.high) / 2], dtype=np.float32)
    twin = WarpTwin("hopper", 3, "3d", chosen=True, seed=[1, 2, 3], device="cpu")
    twin.reset()
    twin.set_points(torch.from_numpy(points))
    np.testing.assert_array_equal(twin.points(), points.astype(np.float64))
    cpus = assert_worlds_follow_cpu(twin, resolved, points)
    twin.restart(np.array([2, 2, 2]))  # a new episode: the point stays until set_points
    np.testing.assert_array_equal(twin.points(), points.astype(np.float64))
    np.testing.assert_array_equal(
        twin.m.body_mass.numpy(), np.float32([e.unwrapped.model.body_mass for e in cpus])
    )
    with pytest.raises(ValueError, match="chosen=True"):
        WarpTwin("hopper", 1, "3d", device="cpu").set_points(points[:1])


STEPS = 84  # past the warm-up: the candidates restart, are drawn and descend on the device


@pytest.mark.warp
@pytest.mark.e2e  # ~30 s of twin training on warp's CPU device: the long tier (.ci/run runs it)
def test_m2td3_trains_on_the_twin_reading_once_a_block(monkeypatch):
    """``train_on_twin`` trains M2TD3 with each episode's point chosen on the device: no read
    back inside a block, and a run's numbers do not depend on the block size."""
    from rrls.agents.on_twin import train_on_twin

    def train(block: int):
        return train_on_twin(
            "m2td3",
            "invertedpendulum",
            seeds=(0, 1),
            steps=STEPS,
            uncertainty="1d",
            device="cpu",
            hyper={**SMALL, "hatomega_number": 3},
            block=block,
            progress_every=STEPS,
        )

    whole = train(STEPS)
    reads = HostReads(monkeypatch)
    blocks = train(7)
    monkeypatch.undo()
    inside = sorted(set(reads.at) - {0, *range(7, STEPS, 7), STEPS})
    assert not inside, f"host reads inside a block, at steps {inside}"
    assert blocks.returns == whole.returns and all(len(r) > 3 for r in whole.returns)
    obs = np.random.default_rng(0).normal(size=(5, 4))
    for x, y in zip(whole.policies, blocks.policies, strict=True):
        np.testing.assert_array_equal(x(obs), y(obs))
