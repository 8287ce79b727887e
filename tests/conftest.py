"""Shared fixtures: keep MuJoCo's warnings out of the working tree."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
import warnings
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import mujoco
import numpy as np
import pytest

STOP_AT_ENV = "RRLS_STOP_AT"  # rrls.agents.run.STOP_AT_ENV (not imported here: no torch)
TASK_KEYS = ["ant", "halfcheetah", "hopper", "humanoidstandup", "invertedpendulum", "walker"]


@pytest.fixture(autouse=True, scope="session")
def _mujoco_warnings_to_python():
    """MuJoCo appends warnings to MUJOCO_LOG.TXT in the cwd; route them to Python instead."""
    previous = mujoco.get_mju_user_warning()
    mujoco.set_mju_user_warning(lambda msg: warnings.warn(f"MuJoCo: {msg}", stacklevel=1))
    yield
    mujoco.set_mju_user_warning(previous)


@pytest.fixture(autouse=True)
def _in_tmp_dir(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)


def e2e_after_first(values: list) -> list:
    """Parametrize values: the first in the default tier (a smoke check of the path on every
    change), the others marked ``e2e`` (``.ci/run`` runs them right after the default tier)."""
    return [*values[:1], *(pytest.param(v, marks=pytest.mark.e2e) for v in values[1:])]


def rollout(env, actions, seed: int = 0, reset_options=None):
    """Observations, rewards and flags of a fixed action sequence (stops at the episode's end)."""
    obs, _ = env.reset(seed=seed, options=reset_options)
    out = [obs]
    rewards, flags = [], []
    for a in actions:
        obs, r, term, trunc, _ = env.step(a)
        out.append(obs)
        rewards.append(r)
        flags.append((term, trunc))
        if term or trunc:
            break
    return np.array(out), np.array(rewards), flags


def fixed_actions(space, n: int, seed: int = 123) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return rng.uniform(space.low, space.high, size=(n, *space.shape)).astype(space.dtype)


@contextmanager
def stopping_at(step: int) -> Iterator[None]:
    """Training started inside stops as if killed right after its first checkpoint at or past
    ``step`` (``rrls.agents.run.STOP_AT_ENV``: fault injection, outside every config)."""
    os.environ[STOP_AT_ENV] = str(step)
    try:
        yield
    finally:
        os.environ.pop(STOP_AT_ENV, None)


def policy_arrays(run_dir) -> dict:
    """A finished run's exported weights (policy and adversary), by file and array name."""
    out = {}
    for name in ("policy.npz", "adversary.npz"):
        if (run_dir / name).exists():
            with np.load(run_dir / name) as f:
                out.update({f"{name}:{k}": f[k] for k in f.files if k != "header"})
    return out


def interrupt_rrls(
    args: list[str], cwd: Path, ready: Path, wait: float = 120, sig: int = signal.SIGINT
) -> subprocess.CompletedProcess:
    """Run ``rrls ARGS`` in its own process group, press Ctrl-C (SIGINT to the group, as a
    terminal sends it; ``sig=SIGTERM``: a scheduler's stop, to every process of the job) once
    ``ready`` exists (or after ``wait`` s), and return what it printed."""
    # Python leaves SIGINT ignored if it starts ignored (a suite launched in the background by a
    # non-interactive shell): give the child Ctrl-C's default, as a terminal would
    code = "import signal, sys; signal.signal(signal.SIGINT, signal.default_int_handler); "
    code += f"from rrls.cli import main; sys.exit(main({args!r}))"
    env = {**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[1])}
    proc = subprocess.Popen(
        [sys.executable, "-c", code], cwd=cwd, env=env, text=True, start_new_session=True,
        stdout=subprocess.PIPE, stderr=subprocess.PIPE,
    )  # fmt: skip
    deadline = time.time() + wait
    while not ready.exists() and proc.poll() is None and time.time() < deadline:
        time.sleep(0.2)
    time.sleep(1.0)
    if proc.poll() is None:
        os.killpg(proc.pid, sig)
    try:
        out, err = proc.communicate(timeout=120)
    except subprocess.TimeoutExpired:  # never leave a run training behind a failed test
        os.killpg(proc.pid, signal.SIGKILL)
        proc.communicate()
        raise
    return subprocess.CompletedProcess(args, proc.returncode, out, err)


class HostReads:
    """The twin tests' host-read counter (a device-resident loop reads once a block): every
    read of a tensor or warp array back to the host, with the twin's step count at each
    (``WarpTwin.step`` counted by a wrapper)."""

    def __init__(self, monkeypatch: pytest.MonkeyPatch) -> None:
        import torch
        import warp as wp

        from rrls.twin import WarpTwin

        self.steps, self.at = 0, []
        for owner, name in (
            (torch.Tensor, "cpu"),
            (torch.Tensor, "numpy"),
            (torch.Tensor, "item"),
            (torch.Tensor, "tolist"),
            (torch.Tensor, "__array__"),
            (torch.Tensor, "__bool__"),
            (torch.Tensor, "__float__"),
            (wp.array, "numpy"),
        ):
            monkeypatch.setattr(owner, name, self.counted(getattr(owner, name)))
        step = WarpTwin.step

        def counted_step(twin, actions):
            self.steps += 1
            return step(twin, actions)

        monkeypatch.setattr(WarpTwin, "step", counted_step)

    def counted(self, method):
        def read(*args, **kwargs):
            self.at.append(self.steps)
            return method(*args, **kwargs)

        return read


def assert_worlds_follow_cpu(twin, resolved, points, steps: int = 10) -> list:
    """Each world of ``twin`` against a CPU env at its point (``points``, one row per world) from
    its state: the same masses, then ``steps`` steps of the same random actions within the
    twin's tolerances (qpos 1e-5 after the first step, 1e-4 after; reward 1e-3; the same
    terminations). Returns the CPU envs."""
    from rrls.twin.agreement import cpu_env_at

    n = twin.num_envs
    qpos, qvel = twin.state()
    cpus = [cpu_env_at(resolved, points[w], qpos[w], qvel[w]) for w in range(n)]
    np.testing.assert_array_equal(
        twin.m.body_mass.numpy(), np.float32([e.unwrapped.model.body_mass for e in cpus])
    )
    rng, space = np.random.default_rng(0), twin.single_action_space
    for t in range(steps):
        action = rng.uniform(space.low, space.high, (n, space.shape[0])).astype(np.float32)
        _, reward, terminated, _, _ = twin.step(action)
        tq, _ = twin.state()
        for w, env in enumerate(cpus):
            _, r, term, _, _ = env.step(action[w].astype(np.float64))
            assert bool(term) == bool(terminated[w])
            assert np.abs(tq[w] - env.unwrapped.data.qpos).max() < (1e-5 if t == 0 else 1e-4)
            assert abs(float(reward[w]) - r) < 1e-3
    return cpus


def random_policy(task: str, seed: int = 3):
    """A small random MLP policy (32-32) for ``task``'s registered environment."""
    import gymnasium as gym

    from rrls.evaluation import MLPPolicy

    env = gym.make(f"rrls/robust-{task}-v0")
    return MLPPolicy.random(
        env.observation_space.shape[0], env.action_space.shape[0], hidden=(32, 32), seed=seed
    )
