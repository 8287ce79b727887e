"""paper=True writes exactly the model entries the original RRLS code writes, row for row.

The table below is read off the original code, SuReLI/RRLS at 0c43dc9 (``rrls/envs/<file>``,
the ``_change_params`` methods; the v4-era files, e.g. 75a1c8d, write the same entries:
``half_cheetah.py:114`` ``geom_friction[:, 0]``, ``hopper.py:92`` and ``walker.py:109``
``geom_friction[0, 0]``). Each test sets one parameter of a paper env and compares every array of
``MjModel`` (and ``MjData.xfrc_applied``) before and after: the entries that changed must be the
original's, and nothing else (no derived constants: the original never calls ``mj_setConst``).
"""

from __future__ import annotations

import warnings
from typing import NamedTuple

import gymnasium as gym
import numpy as np
import pytest

from rrls.envs import FORCE_ENVS, ROBUST_ENVS

ALL = slice(None)


class Original(NamedTuple):
    """One task of the original code: what its rows write, and where (file:first-last line)."""

    file: str
    #: ``worldfriction``'s rows of ``geom_friction[:, 0]`` (ALL or [0]) and its line; None: no row
    friction: tuple[object, int] | None
    #: ``<part>mass`` -> body index of ``body_mass[b] = ...``, and the lines of those writes
    masses: dict[str, int]
    mass_lines: str
    #: force part -> body index b of ``xfrc_applied[b, k]`` (k = 0, 1, 2 for _x, _y, _z)
    forces: dict[str, int]
    force_lines: str


ORIGINAL = {
    "ant": Original(
        "ant.py",
        None,
        {
            "torsomass": 1, "frontleftlegmass": 2, "frontleftlegauxmass": 3,
            "frontleftleganklemass": 4, "frontrightlegmass": 5, "frontrightlegauxmass": 6,
            "frontrightleganklemass": 7, "backleftlegmass": 8, "backleftlegauxmass": 9,
            "backleftleganklemass": 10, "backrightlegmass": 11, "backrightlegauxmass": 12,
            "backrightleganklemass": 13,
        },
        "ant.py:244-280",
        {
            "torso": 1, "frontleftleg": 2, "frontleftlegaux": 3, "frontleftlegankle": 4,
            "frontrightleg": 5, "frontrightlegaux": 6, "frontrightlegankle": 7,
            "backleftleg": 8, "backleftlegaux": 9, "backleftlegankle": 10, "backrightleg": 11,
            "backrightlegaux": 12, "backrightlegankle": 13,
        },
        "ant.py:470-584",
    ),
    "halfcheetah": Original(
        "half_cheetah.py",
        (ALL, 175),  # geom_friction[:, 0]: every geom
        {
            "torsomass": 1, "backthighmass": 2, "backshinmass": 3, "backfootmass": 4,
            "forwardthighmass": 5, "forwardshinmass": 6, "forwardfootmass": 7,
        },
        "half_cheetah.py:177-189",
        {
            "torso": 1, "backthigh": 2, "backshin": 3, "backfoot": 4, "forwardthigh": 5,
            "forwardshin": 6, "forwardfoot": 7,
        },
        "half_cheetah.py:306-346",
    ),
    "hopper": Original(
        "hopper.py",
        ([0], 137),  # geom_friction[0, 0]: the floor
        {"torsomass": 1, "thighmass": 2, "legmass": 3, "footmass": 4},
        "hopper.py:140-149",
        {"torso": 1, "thigh": 2, "leg": 3, "foot": 4},
        "hopper.py:229-262",
    ),
    "humanoidstandup": Original(
        "humanoid.py",
        None,
        {
            "torsomass": 1, "lwaistmass": 2, "pelvismass": 3, "rightthighmass": 4,
            "rightshinmass": 5, "rightfootmass": 6, "leftthighmass": 7, "leftshinmass": 8,
            "leftfootmass": 9, "rightupperarmmass": 10, "rightlowerarmmass": 11,
            "leftupperarmmass": 12, "leftlowerarmmass": 13,
        },
        "humanoid.py:228-264",
        {
            "torso": 1, "lwais": 2, "pelvis": 3, "rightthigh": 4, "rightshin": 5,
            "rightfoot": 6, "leftthigh": 7, "leftshin": 8, "leftfoot": 9, "rightupperarm": 10,
            "rightlowerarm": 11, "leftupperarm": 12, "leftlowerarm": 13,
        },
        "humanoid.py:452-566",
    ),
    "invertedpendulum": Original(
        "pendulum.py",
        None,
        {"cartmass": 1, "polemass": 2},
        "pendulum.py:88-90",
        {"cart": 1, "pole": 2},
        "pendulum.py:142-152",
    ),
    "walker": Original(
        "walker.py",
        ([0], 169),  # geom_friction[0, 0]: the floor
        {
            "torsomass": 1, "thighmass": 2, "legmass": 3, "footmass": 4, "leftthighmass": 5,
            "leftlegmass": 6, "leftfootmass": 7,
        },
        "walker.py:172-190",
        {
            "torso": 1, "thigh": 2, "leg": 3, "foot": 4, "leftthigh": 5, "leftleg": 6,
            "leftfoot": 7,
        },
        "walker.py:306-366",
    ),
}  # fmt: skip


def _writes(task: str, family: str) -> dict[str, tuple[str, tuple]]:
    """Parameter -> (array, index) the original writes."""
    orig = ORIGINAL[task]
    if family == "force":
        return {
            f"{part}force_{axis}": ("xfrc_applied", (b, k))
            for part, b in orig.forces.items()
            for k, axis in enumerate("xyz")
        }
    out = {name: ("body_mass", (b,)) for name, b in orig.masses.items()}
    if orig.friction is not None:
        rows = orig.friction[0]
        out["worldfriction"] = ("geom_friction", (rows, 0))
    return out


def _snapshot(env) -> dict[str, np.ndarray]:
    model = env.unwrapped.model
    arrays = {}
    for name in dir(model):
        if name.startswith("_"):
            continue
        value = getattr(model, name, None)
        if isinstance(value, np.ndarray):
            arrays[name] = value.copy()
    for name in dir(model.opt):
        value = getattr(model.opt, name)
        if isinstance(value, (float, int, np.ndarray)):
            arrays[f"opt.{name}"] = np.atleast_1d(np.array(value, copy=True))
    arrays["xfrc_applied"] = env.unwrapped.data.xfrc_applied.copy()
    return arrays


def _changed(before: dict, after: dict) -> set[tuple[str, tuple[int, ...]]]:
    out = set()
    for name, old in before.items():
        new = after[name]
        for idx in zip(*np.nonzero(old != new)):
            out.add((name, tuple(int(i) for i in idx)))
    return out


def _expected(env, array: str, index: tuple) -> set[tuple[str, tuple[int, ...]]]:
    shape = _snapshot(env)[array].shape
    mask = np.zeros(shape, dtype=bool)
    mask[index] = True
    return {(array, tuple(int(i) for i in idx)) for idx in zip(*np.nonzero(mask))}


def _paper(task: str, family: str):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        return (ROBUST_ENVS if family == "robust" else FORCE_ENVS)[task](paper=True)


@pytest.mark.parametrize("family", ["robust", "force"])
@pytest.mark.parametrize("task", list(ORIGINAL))
def test_paper_env_writes_exactly_the_original_fields(task, family):
    env = _paper(task, family)
    writes = _writes(task, family)
    # the original's parameters, each one a row of the paper env (names as the original spells)
    assert set(writes) <= set(env.unwrapped.param_names())
    for name, (array, index) in writes.items():
        before = _snapshot(env)
        value = 0.987654 if family == "robust" else 1.234567
        env.unwrapped.set_params(**{name: value})
        changed = _changed(before, _snapshot(env))
        assert changed == _expected(env, array, index), (task, name)
        env.unwrapped.reset_params()


@pytest.mark.parametrize("task", ["halfcheetah", "hopper", "walker"])
def test_paper_worldfriction_is_the_original_write_bit_for_bit(task):
    """The paper env with worldfriction set runs as the original's env with its write."""
    env = _paper(task, "robust")
    env.set_params(worldfriction=0.1)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        plain = gym.make(env.unwrapped.task.paper_id).unwrapped
    rows, _ = ORIGINAL[task].friction
    plain.model.geom_friction[rows, 0] = 0.1
    actions = np.random.default_rng(0).uniform(-1, 1, (200, *plain.action_space.shape))
    for e in (env, plain):
        e.reset(seed=0)
    for a in actions:
        out, ref = env.step(a), plain.step(a)
        np.testing.assert_array_equal(out[0], ref[0])
        assert out[1] == ref[1]


def test_halfcheetah_paper_friction_below_the_geoms_acts():
    """Issue 26: the floor-only write left every friction below the geoms' 0.4 inert."""
    actions = np.random.default_rng(0).uniform(-1, 1, (300, 6))
    returns = []
    for friction in (0.1, 0.39):
        env = _paper("halfcheetah", "robust")
        env.set_params(worldfriction=friction)
        env.reset(seed=0)
        returns.append(sum(env.step(a)[1] for a in actions))
    assert returns[0] != returns[1]
