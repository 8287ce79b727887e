"""Tutorial: add your own robust task with ``rrls.register_task`` (tutorial b).

Any Gymnasium MuJoCo env becomes an rrls task by *declaring* its parameters and uncertainty
sets as data: which body, joint or actuator each parameter writes, looked up by name in the
compiled model (nominal values are read from the model, never typed in). Here:
InvertedDoublePendulum-v5 with a 2-parameter set over the two poles' masses, plus the hinges'
damping as a second set. After registration everything rrls offers works with the new key:

* ``gym.make("rrls/robust-mydoublependulum-v0")`` and the DR / adversarial ids,
* ``rrls.envs.get_uncertainty_set`` / ``resolve``, ``evaluate``, ``search_worst_case``,
* the wrappers, ``rrls train --task mydoublependulum`` and ``rrls benchmark --tasks ...``.

For the ``rrls`` command (and the processes ``rrls benchmark`` spawns) to see the task, ship it
in a package with an entry point in your ``pyproject.toml``::

    [project.entry-points."rrls.tasks"]
    mydoublependulum = "mypackage.tasks:register"   # a function calling rrls.register_task

Run: ``python docs/tutorials/add_a_task.py`` (``--smoke``: a few seconds, as the tests do).
"""

from __future__ import annotations

import argparse

import gymnasium as gym
import numpy as np

import rrls
from rrls.envs import get_uncertainty_set
from rrls.evaluation import Protocol, evaluate, search_worst_case
from rrls.params import joint_params, mass_params
from rrls.wrappers import DomainRandomization


def register() -> None:
    """Declare the task (this is what an entry point would call)."""
    rrls.register_task(
        "mydoublependulum",
        "InvertedDoublePendulum-v5",
        name="MyDoublePendulum",  # classes RobustMyDoublePendulum, ForceMyDoublePendulum
        # body names in the Gymnasium XML: cart, pole, pole2; joints: slider, hinge, hinge2
        params=mass_params({"cart": "cart", "pole": "pole", "pole2": "pole2"})
        + joint_params({"hinge": "hinge", "hinge2": "hinge2"}, kinds=("damping",)),
        sets={
            "2d": {"polemass": (1.0, 10.0), "pole2mass": (1.0, 10.0)},
            "damping": {"hingedamping": (0.0, 2.0), "hinge2damping": (0.0, 2.0)},
        },
        # forces: by default one per body of a mass row (cartforce_x, poleforce_y, ...)
        planar=True,
    )


def lqr_like(obs: np.ndarray) -> np.ndarray:
    """A hand-made linear policy (push the cart under the poles), batch in, batch out."""
    sin1, sin2 = obs[:, 1], obs[:, 2]
    v_cart, w1, w2 = obs[:, 5], obs[:, 6], obs[:, 7]
    action = 3.0 * sin1 + 6.0 * sin2 + 0.2 * v_cart + 0.6 * w1 + 0.6 * w2
    return np.clip(action, -1.0, 1.0)[:, None]


def main(smoke: bool) -> None:
    register()
    steps = 50 if smoke else 1000

    # 1. the Gymnasium ids
    env = gym.make("rrls/robust-mydoublependulum-v0")
    print("parameters:", env.get_params())  # nominal values read from the model
    env.set_params(pole2mass=6.0)
    obs, info = env.reset(seed=0)
    print("pole2mass now", info["pole2mass"])

    # 2. the sets and a domain-randomised env
    box = get_uncertainty_set("mydoublependulum", "2d")
    print("set:", box)
    dr = DomainRandomization(gym.make("rrls/robust-mydoublependulum-v0"), box)
    _, info = dr.reset(seed=1)
    print("drawn:", info["randomized_params"])
    dr_id = gym.make("rrls/robust-mydoublependulum-domain-randomization-2d-v0")
    dr_id.reset(seed=2)

    # 3. evaluation over a mesh of the set, and a worst-case search
    protocol = Protocol("2d", mesh=2 if smoke else 10, episodes=1, max_episode_steps=steps)
    result = evaluate(lqr_like, "mydoublependulum", protocol, workers=1)
    print(f"2d set: worst {result.worst_case:.1f} at {result.worst_point}, "
          f"average {result.average_case:.1f}")  # fmt: skip
    damping = evaluate(
        lqr_like, "mydoublependulum", protocol.replace(uncertainty="damping"), workers=1
    )
    print(f"damping set: worst {damping.worst_case:.1f} at {damping.worst_point}")
    budget = 8 if smoke else 100
    search = search_worst_case(
        lqr_like, "mydoublependulum", budget=budget, workers=1, protocol=protocol
    )
    print(f"search: worst {search.value:.1f} at {search.params}")
    rrls.registry.unregister_task("mydoublependulum")  # the tests run this script in-process
    print("next: rrls train --algo m2td3 --task mydoublependulum --uncertainty 2d "
          "(with the task in a package's `rrls.tasks` entry point)")  # fmt: skip


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--smoke", action="store_true", help="tiny sizes (the test suite's)")
    main(parser.parse_args().smoke)
