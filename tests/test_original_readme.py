"""The original RRLS README's examples run as written against rrls (issue 26: original code
runs unchanged). Each test is one example of SuReLI/RRLS's README.md at 0c43dc9, copied as code
with its line numbers; the only change is marked where the README's own example fails on the
original package too.
"""

from __future__ import annotations

import pytest


def test_readme_lists_the_registered_ids():  # README.md:56-61
    import gymnasium as gym

    found = []
    for env in gym.envs.registry:
        if "rrls/robust" in env:
            found.append(env)
    assert "rrls/robust-ant-v0" in found


def test_readme_example_of_usage_sets_every_parameter_to_one():  # README.md:65-89
    import gymnasium as gym

    import rrls  # noqa: F401

    env = gym.make("rrls/robust-ant-v0")
    params = env.get_params()  # Parameters will be None if reset method hasn't been called.

    # Set all parameters to 1
    params = {k: 1 for k in params.keys()}

    # Modify environment parameters during reset using the options argument
    obs, info = env.reset(options=params)

    # Retrieve environment parameters from the info dictionary
    # README.md:79 reads info["torso_mass"], a key the original never wrote (its info carries
    # "torsomass", ant.py:214-229): a KeyError on the original package as on rrls
    print(info["torsomass"])  # Outputs: all keys are equals to one 1

    terminated, truncated = False, False

    while not (terminated or truncated):
        action = env.action_space.sample()
        obs, reward, terminated, truncated, info = env.step(action)
        print(info["torsomass"])

        # To change environment parameters during an episode, use the set_params method.
        # env.set_params(params)

    # what the example claims: every parameter it was given is now 1
    assert params and all(info[k] == 1 for k in params)
    assert set(params) == {
        "torsomass", "frontleftlegmass", "frontleftlegauxmass", "frontleftleganklemass",
        "frontrightlegmass", "frontrightlegauxmass", "frontrightleganklemass",
        "backleftlegmass", "backleftlegauxmass", "backleftleganklemass", "backrightlegmass",
        "backrightlegauxmass", "backrightleganklemass",
    }  # fmt: skip  # the original's RobustAnt.get_params (ant.py:213-228)


def test_readme_example_with_every_task_and_family():
    """The same example on every id of the original's tasks, robust and force envs alike."""
    import gymnasium as gym

    for env_id in (
        "rrls/robust-ant-v0", "rrls/robust-halfcheetah-v0", "rrls/robust-hopper-v0",
        "rrls/robust-humanoidstandup-v0", "rrls/robust-invertedpendulum-v0",
        "rrls/robust-walker-v0", "rrls/force-hopper-v0", "rrls/force-ant-v0",
    ):  # fmt: skip
        env = gym.make(env_id)
        params = {k: 1 for k in env.get_params().keys()}
        _, info = env.reset(seed=0, options=params)
        env.step(env.action_space.sample())
        assert all(info[k] == 1 for k in params), env_id


def test_readme_original_keys_are_get_params_and_new_kinds_are_asked_for():
    """``get_params()`` is the original's dict; ``kinds="all"`` adds the new kinds."""
    import gymnasium as gym

    from rrls.envs import FORCE_ENVS, ROBUST_ENVS

    hopper = gym.make("rrls/robust-hopper-v0")
    assert list(hopper.get_params()) == [
        "worldfriction", "torsomass", "thighmass", "legmass", "footmass"
    ]  # fmt: skip  # hopper.py:114-121
    every = hopper.get_params(kinds="all")
    assert {"timestep", "gravity", "footfriction", "thighdamping"} <= set(every)
    assert set(hopper.get_params(kinds="damping")) == {"thighdamping", "legdamping", "footdamping"}
    assert set(hopper.get_params(kinds=("mass",))) == set(every) & {
        "torsomass", "thighmass", "legmass", "footmass"
    }  # fmt: skip
    with pytest.raises(ValueError, match="unknown parameter kind.*valid: 'all'"):
        hopper.get_params(kinds="masses")
    # the original's force envs list _x, _y, _z of every part (pendulum.py:130-138)
    force = FORCE_ENVS["invertedpendulum"]()
    assert list(force.get_params()) == [
        "poleforce_x", "poleforce_y", "poleforce_z", "cartforce_x", "cartforce_y", "cartforce_z"
    ]  # fmt: skip
    assert list(ROBUST_ENVS["invertedpendulum"]().get_params()) == ["polemass", "cartmass"]


def test_readme_uncertainty_sets():  # README.md:105-134
    from rrls.envs.ant import AntParamsBound

    params_bound_2d = AntParamsBound.TWO_DIM.value
    assert params_bound_2d == {"torsomass": [0.1, 3.0], "frontleftlegmass": [0.01, 3.0]}

    rarl_params_bound = AntParamsBound.RARL.value
    assert rarl_params_bound == {
        "torsoforce_x": [-3.0, 3.0],
        "torsoforce_y": [-3.0, 3.0],
        "frontleftlegforce_x": [-3.0, 3.0],
        "frontleftlegforce_y": [-3.0, 3.0],
        "frontrightlegforce_x": [-3.0, 3.0],
        "frontrightlegforce_y": [-3.0, 3.0],
    }


def test_readme_evaluate():  # README.md:140-155
    with pytest.warns(DeprecationWarning, match="default_evaluation_set"):  # works, and says so
        from rrls.evaluate import EVALUATION_ROBUST_ANT_3D  # Set consisting of 10^3 environments

    assert len(EVALUATION_ROBUST_ANT_3D) == 1000

    from rrls.envs.ant import AntParamsBound, RobustAnt
    from rrls.evaluate import generate_evaluation_set

    with pytest.warns(DeprecationWarning, match="use mesh="):
        eval_env_set = generate_evaluation_set(
            modified_env=RobustAnt,
            param_bounds=AntParamsBound.THREE_DIM.value,
            nb_mesh_dim=3,
        )
    assert len(eval_env_set) == 27
    env = eval_env_set[26]
    env.reset(seed=0)
    assert env.get_params()["torsomass"] == pytest.approx(3.0)
