"""Shared fixtures: keep MuJoCo's warnings out of the working tree."""

from __future__ import annotations

import warnings

import mujoco
import numpy as np
import pytest

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
