"""The environments of a group of runs, stepped in lockstep: in the training process, or spread
over worker processes.

Why workers: on a GPU a group's update takes about a millisecond, while stepping 32 MuJoCo envs
one after the other takes longer than that; worker processes (one core each) step their share
of the envs at the same time. On a CPU the update dominates and the envs stay in-process.
Each env keeps its own seeded generator wherever it lives, so workers change no number.
"""

from __future__ import annotations

import multiprocessing as mp
from collections.abc import Callable
from typing import Any

import numpy as np

from rrls.agents.streams import rng_state, set_rng_state
from rrls.physics import is_paper


class LocalEnvs:
    """The group's envs in this process."""

    def __init__(self, make: Callable[[], Any], n: int) -> None:
        self.envs = [make() for _ in range(n)]

    def step(self, actions: list[Any]) -> list[tuple]:
        """``(obs, reward, terminated, info)`` of every env after its action."""
        out = []
        for env, action in zip(self.envs, actions):
            obs, reward, terminated, _, info = env.step(action)
            out.append((obs, reward, terminated, info))
        return out

    def step_one(self, k: int, action: Any) -> tuple:
        obs, reward, terminated, _, info = self.envs[k].step(action)
        return obs, reward, terminated, info

    def reset(self, k: int, seed: int | None, options: dict | None) -> np.ndarray:
        return self.envs[k].reset(seed=seed, options=options)[0]

    def begin(self, k: int, seed: int | None, options: dict | None) -> tuple[str, np.ndarray]:
        """An episode's start: the env's generator state (to replay it), then its reset."""
        return rng_state(self.envs[k].unwrapped.np_random), self.reset(k, seed, options)

    def set_rng_state(self, k: int, state: str) -> None:
        set_rng_state(self.envs[k].unwrapped.np_random, state)

    def close(self) -> None:
        for env in self.envs:
            env.close()


def _worker(make: Callable[[], Any], indices: list[int], conn: Any) -> None:
    from rrls._proc import die_with_parent

    die_with_parent()
    local = LocalEnvs(make, len(indices))
    position = {k: i for i, k in enumerate(indices)}
    while True:
        command, *args = conn.recv()
        if command == "close":
            local.close()
            conn.close()
            return
        if command == "step":  # {k: action}
            conn.send({k: local.step_one(position[k], action) for k, action in args[0].items()})
        else:  # begin / reset / set_rng_state / step_one on env k
            k, *rest = args
            conn.send(getattr(local, command)(position[k], *rest))


class WorkerEnvs:
    """The group's envs spread over ``workers`` processes, each stepping its share at once."""

    def __init__(self, make: Callable[[], Any], n: int, workers: int) -> None:
        if mp.current_process().daemon:
            raise RuntimeError(
                f"env workers={workers}: a daemonic process (a multiprocessing.Pool worker) "
                "cannot start worker processes; use env_workers=0 (rrls train --workers 0)"
            )
        ctx = mp.get_context("spawn")
        shares = np.array_split(np.arange(n), min(workers, n))
        self.owner: dict[int, Any] = {}
        self.pipes, self.procs = [], []
        for share in shares:
            parent, child = ctx.Pipe()
            proc = ctx.Process(target=_worker, args=(make, share.tolist(), child), daemon=True)
            proc.start()
            child.close()
            self.pipes.append(parent)
            self.procs.append(proc)
            for k in share.tolist():
                self.owner[k] = parent

    def step(self, actions: list[Any]) -> list[tuple]:
        for pipe in self.pipes:  # every worker starts at once
            pipe.send(("step", {k: a for k, a in enumerate(actions) if self.owner[k] is pipe}))
        results: dict[int, tuple] = {}
        for pipe in self.pipes:
            results.update(pipe.recv())
        return [results[k] for k in range(len(actions))]

    def _call(self, command: str, k: int, *args: Any) -> Any:
        pipe = self.owner[k]
        pipe.send((command, k, *args))
        return pipe.recv()

    def step_one(self, k: int, action: Any) -> tuple:
        return self._call("step_one", k, action)

    def reset(self, k: int, seed: int | None, options: dict | None) -> np.ndarray:
        return self._call("reset", k, seed, options)

    def begin(self, k: int, seed: int | None, options: dict | None) -> tuple[str, np.ndarray]:
        return self._call("begin", k, seed, options)

    def set_rng_state(self, k: int, state: str) -> None:
        self._call("set_rng_state", k, state)

    def close(self) -> None:
        for pipe, proc in zip(self.pipes, self.procs):
            try:
                pipe.send(("close",))
            except OSError:
                pass
            proc.join(timeout=5)


def make_envs(make: Callable[[], Any], n: int, workers: int) -> LocalEnvs | WorkerEnvs:
    """``workers`` 0: in this process; else that many worker processes (at most ``n``)."""
    return LocalEnvs(make, n) if workers <= 0 else WorkerEnvs(make, n, workers)


def task_env(task: str, uncertainty: Any = "nominal", paper: bool = False) -> tuple[Any, Any]:
    """A bare env of ``task`` (no time limit: the loop truncates) of the family ``uncertainty``
    needs (``rrls.envs.resolve``, the one place that decides), and the set's box (``None`` for
    the nominal task). ``paper``: on the paper's physics (the paper twin, ``paper_class``)."""
    from rrls.envs import paper_class, resolve

    resolved = resolve(task, uncertainty)
    cls = paper_class(resolved.env_class) if paper else resolved.env_class
    return cls(), (None if resolved.is_nominal else resolved.box)


def env_factory(algo: Any, config: Any, hyper: Any) -> Any:
    """What builds ``config``'s training env (picklable, for worker processes): the algorithm's
    ``make_env(task, uncertainty, hyper)``, with ``paper=True`` on the paper's physics (a
    plug-in whose ``make_env`` takes no ``paper`` keyword cannot train there: refused)."""
    import functools
    import inspect

    if not is_paper(config.physics):
        return functools.partial(algo.make_env, config.task, config.training_set(), hyper)

    if "paper" not in inspect.signature(algo.make_env).parameters:
        raise ValueError(
            f"algorithm {algo.name!r}: its make_env takes no 'paper' keyword, so it cannot "
            "train on the paper's physics (--physics paper)"
        )
    return functools.partial(algo.make_env, config.task, config.training_set(), hyper, paper=True)
