"""The envs of a group of runs on the MuJoCo Warp twin (``rrls train --simulator warp``) for
learners without the device-resident methods (a plug-in's; M2TD3 with ``same_start``, every
episode from the run's one first state: the built-ins run in ``rrls.agents.resident``): the
same interface as ``rrls.agents.envs.LocalEnvs``, so the CPU envs' collector
(``rrls.agents.stepwise``) steps them and the driver's checkpoints, logs, periodic evaluations
and run files are the CPU path's.

Run ``k`` owns world ``k`` and a CPU env of its own. An episode starts on the CPU env (reset
with the run's seed and the learner's options: DR's draw, M2TD3's chosen point), and the world
becomes a copy of it (``WarpTwin.put_world``: its point's model fields, its state); every step
of the group is one step of all worlds on the device. Episodes end where the loop says
(termination from the twin, the time limit from the loop), so no world resets on its own.

What differs from the CPU path, on purpose: a checkpoint's episode in progress is not replayed
on resume (float32 steps on another device would not reproduce it); the resumed run starts
that episode again from its first state and point (same seed, same options), so a resumed run
is another draw of the same training, as any twin run is from a CPU one.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from rrls.agents.resident import quiet_warp
from rrls.agents.streams import rng_state, set_rng_state

#: the largest episode the twin counts to: the loop truncates, the twin never does
_NO_LIMIT = 2**30


class TwinEnvs:
    """``n`` runs' envs on a ``WarpTwin`` of ``task`` (see the module's docstring)."""

    #: the loop restarts the episode in progress on resume instead of replaying it
    replays = False

    def __init__(
        self, make: Callable[[], Any], n: int, task: str, uncertainty: Any, device: str
    ) -> None:
        from rrls.twin import WarpTwin

        quiet_warp()
        self.cpu = [make() for _ in range(n)]
        # built over the training set: a parameter the twin cannot vary is refused here
        self.twin = WarpTwin(task, n, uncertainty, device=device, max_episode_steps=_NO_LIMIT)
        self.twin.reset(seed=0)  # every world's buffers; each is put at its run's state below
        self.n = n

    def step(self, actions: list[Any]) -> list[tuple]:
        """``(obs, reward, terminated, info)`` of every world after its action."""
        obs, reward, terminated, _, info = self.twin.step(np.stack(actions).astype(np.float32))
        ended = info["_final_obs"]
        last = np.where(ended[:, None], info["final_obs"], obs).astype(np.float64)
        return [(last[k], float(reward[k]), bool(terminated[k]), {}) for k in range(self.n)]

    def begin(self, k: int, seed: int | None, options: dict | None) -> tuple[str, np.ndarray]:
        """Run ``k``'s episode start: its CPU env's generator state (to start it again), its
        reset, and world ``k`` put at that state and point."""
        env = self.cpu[k]
        state = rng_state(env.unwrapped.np_random)
        obs = env.reset(seed=seed, options=options)[0]
        self.twin.put_world(k, env)
        return state, obs

    def set_rng_state(self, k: int, state: str) -> None:
        set_rng_state(self.cpu[k].unwrapped.np_random, state)

    def step_one(self, k: int, action: Any) -> tuple:
        raise NotImplementedError("a twin world is not stepped alone (the loop restarts episodes)")

    def close(self) -> None:
        self.twin.close()
        for env in self.cpu:
            env.close()


__all__ = ["TwinEnvs"]
