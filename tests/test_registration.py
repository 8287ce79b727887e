"""Registered ids, cheap import, registration by Gymnasium's `module:id` syntax (no hook)."""

from __future__ import annotations

import importlib.util
import pathlib
import subprocess
import sys

import gymnasium as gym
import pytest

import rrls
from rrls.envs import TASKS

PAPER = ("ant", "halfcheetah", "hopper", "humanoidstandup", "invertedpendulum", "walker")


def _all_ids(keys=None):
    ids = []
    for key, task in TASKS.items():
        if keys is not None and key not in keys:
            continue
        ids += [f"rrls/robust-{key}-v0", f"rrls/force-{key}-v0"]
        ids += [f"rrls/robust-{key}-adversarial-{d}-v0" for d in task.sets if d != "rarl"]
        ids += [f"rrls/robust-{key}-domain-randomization-{d}-v0" for d in task.sets if d != "rarl"]
        ids += [f"rrls/robust-{key}-adversarial-forces-v0"]
        ids += [
            f"rrls/probabilistic-action-robust-{key}-v0",
            f"probabilistic-action-robust-{key}-v0",
        ]
    return ids


def test_every_id_is_registered_with_walker_adversarial():
    ids = _all_ids(PAPER)
    assert "rrls/robust-walker-adversarial-3d-v0" in ids
    assert "rrls/robust-invertedpendulum-adversarial-3d-v0" not in ids
    missing = [i for i in ids if i not in gym.registry]
    assert not missing
    assert len(ids) == 6 * 11 - 2  # InvertedPendulum has no 3D set
    missing = [i for i in _all_ids() if i not in gym.registry]  # every task's, users' included
    assert not missing


@pytest.mark.parametrize("env_id", _all_ids())
def test_every_id_makes_and_steps_with_params_interface(env_id):
    env = gym.make(env_id)
    params = env.get_params()
    env.set_params(**{next(iter(params)): next(iter(params.values()))})
    env.reset(seed=0)
    env.step(env.action_space.sample())
    assert gym.make(env.spec).get_params().keys() == params.keys()  # spec round-trips
    env.close()


def test_import_rrls_builds_no_environment():
    code = "import rrls, sys; print(sorted(m for m in sys.modules if m.startswith('rrls')))"
    root = pathlib.Path(__file__).resolve().parents[1]
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True, cwd=root
    )
    assert "rrls.envs'" not in out.stdout and "rrls._registration" in out.stdout


def test_gymnasiums_module_syntax_registers_the_ids_without_import_rrls():
    """Gymnasium 1.x has no plugin hook: ``gym.make("rrls:rrls/...")`` imports rrls itself
    (``gymnasium.envs.registration._find_spec``); the bare id needs ``import rrls`` first, as in
    the original code, and nothing rrls installs runs at interpreter start."""
    code = (
        "import sys, gymnasium as gym\n"
        "try:\n    gym.make('rrls/robust-hopper-v0')\n"
        "except gym.error.NamespaceNotFound:\n    print('needs import rrls')\n"
        "assert 'rrls' not in sys.modules\n"
        "env = gym.make('rrls:rrls/robust-hopper-v0')\n"
        "env.set_params(torsomass=2.0); print(env.get_params()['torsomass'])\n"
        "print(gym.make('rrls/robust-walker-v0').unwrapped.__class__.__name__)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.split() == ["needs", "import", "rrls", "2.0", "RobustWalker2d"]


def test_nothing_is_installed_outside_the_package():
    from importlib.metadata import PackageNotFoundError, distribution

    try:
        files = distribution("rrls").files or []
    except PackageNotFoundError:  # pragma: no cover - the suite runs on an installed rrls
        pytest.skip("rrls is not installed")
    assert not [f for f in files if str(f).endswith(".pth") and "editable" not in str(f)]
    assert importlib.util.find_spec("_rrls_autoregister") is None


def test_version():
    assert rrls.__version__.count(".") == 2
