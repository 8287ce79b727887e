"""The training driver's cadence (``rrls.agents.driver``), on a collector that only reports:
where blocks end, what happens at one step and in which order, the checkpoints' contents, and
the same driver without run directories."""

from __future__ import annotations

import contextlib
import signal
from typing import Any

import pytest

torch = pytest.importorskip("torch")

from rrls.agents import TrainConfig  # noqa: E402
from rrls.agents.driver import LOSS_EVERY, Advance, Driver  # noqa: E402
from rrls.agents.lookup import resolve_run  # noqa: E402
from rrls.agents.run import Run, read_checkpoint  # noqa: E402
from rrls.evaluation.policies import MLPPolicy  # noqa: E402

GROUP = 2


class Collector:
    """Reports the episode ends it was given (``{step: [run, ...]}``) and a loss per step."""

    def __init__(self, block: int, ends: dict[int, list[int]], log: list) -> None:
        self.block, self.ends, self.log = block, ends, log
        self.advances: list[tuple[int, int]] = []
        self.entered = False

    @contextlib.contextmanager
    def running(self):
        self.entered = True
        yield
        self.entered = False

    def start(self, states: list) -> None:
        assert self.entered
        self.log.append(("start", states))

    def advance(self, step: int, n: int) -> Advance:
        self.advances.append((step, n))
        ends = [
            (s - step - 1, k, float(s), 10) for s in range(step + 1, step + n + 1)
            for k in self.ends.get(s, [])
        ]  # fmt: skip
        return Advance(ends, {"critic": torch.full((GROUP,), float(step + n))})

    def next_episode(self, k: int, step: int) -> None:
        self.log.append(("next", k, step))

    def state(self, k: int) -> dict[str, Any]:
        return {"warmup": f"warmup{k}", "twin_episode": k}


class Learner:
    def __init__(self, log: list) -> None:
        self.log = log

    def episode_end(self, k: int, ret: float, length: int) -> dict[str, float]:
        self.log.append(("learner end", k))
        return {}

    def state_dict(self) -> dict[str, Any]:
        return {"w": torch.arange(GROUP * 3, dtype=torch.float32).reshape(GROUP, 3)}

    def export(self, k: int) -> dict[str, Any]:
        return {"policy": MLPPolicy.random(4, 1, (4,), seed=k)}


def test_without_run_directories_blocks_end_at_progress_points_and_ends_keep_their_step():
    log: list = []
    collector = Collector(7, {3: [1], 7: [0], 19: [0, 1], 20: [1], 45: [0]}, log)
    seen, progress = [], []
    driver = Driver(
        Learner(log),
        collector,
        group=GROUP,
        steps=50,
        starts=5,
        on_episode=lambda k, step, ret: seen.append((k, step, ret)),
        on_progress=progress.append,
        progress_every=20,
    )
    driver.run([None, None])
    assert collector.advances == [(0, 7), (7, 7), (14, 6), (20, 7), (27, 7), (34, 6), (40, 7),
                                  (47, 3)]  # fmt: skip
    assert seen == [(1, 3, 3.0), (0, 7, 7.0), (0, 19, 19.0), (1, 19, 19.0), (1, 20, 20.0),
                    (0, 45, 45.0)]  # fmt: skip
    assert progress == [20, 40]
    # each end: the learner's hook, then the collector's next episode, in step order
    ends = [e for e in log if e[0] != "start"]
    assert ends[:4] == [("learner end", 1), ("next", 1, 3), ("learner end", 0), ("next", 0, 7)]


def _runs(tmp_path, steps: int) -> list[Run]:
    runs = []
    for seed in range(GROUP):
        config = TrainConfig(
            algo="td3",
            task="invertedpendulum",
            seed=seed,
            steps=steps,
            out=str(tmp_path / f"seed{seed}"),
            eval_every=500,
            checkpoint_every=300,
            progress=False,
        )
        runs.append(Run(config, False, resolve_run(config).hyper))
    return runs


def test_with_run_directories_one_step_logs_losses_then_evaluates_then_ends_episodes(
    tmp_path, monkeypatch
):
    log: list = []
    monkeypatch.setattr(Run, "log", lambda run, values: log.append(("log", run.step, *values)))
    monkeypatch.setattr(Run, "evaluate", lambda run, policy: log.append(("eval", run.step)))
    real_end = Run.episode_end

    def episode_end(run, ret, length, **extra):
        log.append(("run end", run.step))
        real_end(run, ret, length, **extra)

    monkeypatch.setattr(Run, "episode_end", episode_end)
    runs = _runs(tmp_path, 2 * LOSS_EVERY)
    collector = Collector(64, {LOSS_EVERY: [0], 130: [1]}, log)
    driver = Driver(Learner(log), collector, GROUP, 2 * LOSS_EVERY, starts=100, runs=runs,
                    metas=[{"seed": k} for k in range(GROUP)])  # fmt: skip
    driver.run([None, None])
    block_ends = {step + n for step, n in collector.advances}
    assert {300, 500, 600, 900, LOSS_EVERY, 1200, 1500, 1800, 2 * LOSS_EVERY} <= block_ends
    assert max(n for _, n in collector.advances) == 64
    at = [e for e in log if len(e) > 1 and e[1] == LOSS_EVERY and e[0] != "next"]
    assert at == [
        ("log", LOSS_EVERY, "losses/critic"),
        ("log", LOSS_EVERY, "losses/critic"),
        ("eval", LOSS_EVERY),
        ("eval", LOSS_EVERY),
        ("run end", LOSS_EVERY),
    ]
    assert ("run end", 130) in log  # inside a block: at its own step
    saved = read_checkpoint(runs[1].checkpoint_path)
    assert saved["step"] == 1800 and saved["twin_episode"] == 1 and saved["warmup"] == "warmup1"
    assert saved["learner"]["w"].tolist() == [[3.0, 4.0, 5.0]]
    assert (runs[1].dir / "run.json").exists() and (runs[1].dir / "policy.npz").exists()


def test_ctrl_c_keeps_the_end_of_the_block_it_came_in(tmp_path, monkeypatch):
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        runs = _runs(tmp_path, 400)
        collector = Collector(64, {}, [])
        real = collector.advance

        def advance(step: int, n: int) -> Advance:
            if step == 128:
                signal.raise_signal(signal.SIGINT)
            return real(step, n)

        collector.advance = advance  # type: ignore[method-assign]
        driver = Driver(Learner([]), collector, GROUP, 400, starts=100, runs=runs,
                        metas=[{"seed": k} for k in range(GROUP)])  # fmt: skip
        with pytest.raises(KeyboardInterrupt):
            driver.run([None, None])
    finally:
        signal.signal(signal.SIGINT, previous)
        for run in runs:
            run.close()
    saved = read_checkpoint(runs[0].checkpoint_path)
    assert saved["step"] == 192 and saved["interrupted"] is True
