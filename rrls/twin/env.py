"""``WarpTwin``: a task's MuJoCo Warp twin, a Gymnasium ``VectorEnv`` whose every world runs at a
parameter point of its own, on a GPU (or warp's CPU device).

Why a twin: training the paper's protocol is millions of env steps per run, and CPU MuJoCo is
what a GPU waits on. The twin is built from the same XML as the CPU env, and each world's model
fields are *copied from a CPU model at that world's point* (rrls's ``set_params``: the derived
constants that ``mj_setConst`` recomputes after a mass write included), so the twin's parameter
convention is the CPU env's by construction. Evaluation stays on CPU MuJoCo (float64, exact on
every machine); the twin is float32 and its trajectories drift from the CPU's (chaotically, as
any two float paths do: the docs show by how much).

Points: ``points=`` gives each world a fixed point (an ``(n, dim)`` array over the set's
names); ``domain_randomization=True`` draws each world a new point at every reset, uniformly from
a pool of ``pool`` points of the set drawn from the seed, or from ``pool_seed`` (the pool's fields
are computed once by CPU MuJoCo, so a reset never leaves the device), or with ``pool=0``
(what training uses) uniformly from the whole box, from the world's own stream, the point's
fields written on the device (``rrls.twin.adversary``); ``chosen=True``: the caller's points,
written the same way by ``set_points`` (M2TD3's, as each episode begins); none: the nominal
model. ``modes=`` mixes them, one per world (``WORLD_MODES``: ``nominal``, ``random``,
``chosen``, ``adversary``, an algorithm row's ``set_use``), so several algorithms' runs share
one twin step: a world's numbers are those it has in a twin of its mode alone (MuJoCo Warp
derives the constants of every world at once; those of the nominal worlds are put back as
copied from CPU MuJoCo).

The adversary's point (RARL's game, ``adversary=True``): the action is the protagonist's then
the adversary's, ``(n, nu + dim)``; each step the adversary's ``[-1, 1]`` columns are mapped onto
the set's box with ``DynamicAdversarial``'s arithmetic and written into that world's fields
before the physics (forces into its ``xfrc_applied`` row; masses, friction... into its model
fields, the derived constants recomputed by MuJoCo Warp's ``set_const``), inside the step, with
no host round trip (``rrls.twin.adversary``).

Autoreset is Gymnasium's ``SAME_STEP`` mode: a world that ends returns its first observation of
the next episode, its last one in ``info["final_obs"]``. Arrays stay on the device:
``array="torch"`` returns torch tensors sharing the device memory (and takes torch actions
without a copy), ``"warp"`` warp arrays, ``"numpy"`` (the default) host copies.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import gymnasium as gym
import mujoco
import numpy as np
from gymnasium.vector import AutoresetMode, VectorEnv

from rrls.envs import resolve
from rrls.extras import install_hint
from rrls.registry import get_task
from rrls.twin.catalog import REFUSED, TWIN_TASKS, UNSUPPORTED_FIELDS, fill_formula
from rrls.twin.points import MODEL_FIELDS, host_fields, model_fields, pool_points
from rrls.uncertainty import UncertaintySet

ARRAYS = ("numpy", "torch", "warp")
#: how a world meets the set (``modes=``): the nominal model, a fresh point of the box per
#: episode, the caller's point (``set_points``), the adversary's point at every step
WORLD_MODES = ("nominal", "random", "chosen", "adversary")


def default_set(task: str) -> str:
    """The task's largest paper set (``3d``, else ``2d``, else ``1d``): what DR draws from and
    what ``points`` are over when no set is named."""
    sets = get_task(task).sets
    return next(name for name in ("3d", "2d", "1d", "nominal") if name in sets or name == "nominal")


def _floats(a: Any, n: int) -> Any:
    """A batched warp array seen as ``(n, floats per world)`` float32, sharing its memory."""
    import warp as wp

    return wp.array(
        ptr=a.ptr, dtype=wp.float32, shape=(n, a.capacity // 4 // n), device=a.device, copy=False
    )


class WarpTwin(VectorEnv):
    """A task's MuJoCo Warp twin with ``num_envs`` worlds (see the module's docstring)."""

    metadata = {"autoreset_mode": AutoresetMode.SAME_STEP}

    def __init__(
        self,
        task: str,
        num_envs: int,
        uncertainty: str | UncertaintySet | None = None,
        *,
        points: np.ndarray | None = None,
        domain_randomization: bool = False,
        pool: int = 1024,
        pool_seed: int | None = None,
        seed: int | Sequence[int] = 0,
        device: str = "cuda",
        array: str = "numpy",
        nconmax: int = 32,
        njmax: int = 160,
        max_episode_steps: int | None = None,
        adversary: bool = False,
        chosen: bool = False,
        modes: Sequence[str] | None = None,
        **env_kwargs: Any,
    ) -> None:
        key = get_task(task).key
        if key in REFUSED:
            raise ValueError(f"no Warp twin for {key!r}: {REFUSED[key]}")
        if key not in TWIN_TASKS:
            raise ValueError(f"no Warp twin for {key!r}; tasks with one: {', '.join(TWIN_TASKS)}")
        try:
            import mujoco_warp as mjw
            import warp as wp
        except ImportError as e:
            raise ImportError(
                f"the Warp twin needs the warp extra ({e}); {install_hint('warp')}"
            ) from e

        from rrls.twin import warp_kernels as kernels

        if array not in ARRAYS:
            raise ValueError(f"array={array!r}; valid: {', '.join(ARRAYS)}")
        if not isinstance(num_envs, int) or num_envs < 1:
            raise ValueError(f"num_envs must be a positive integer, got {num_envs!r}")
        if points is not None and domain_randomization:
            raise ValueError("give fixed points or domain_randomization=True, not both")
        if adversary and (points is not None or domain_randomization):
            raise ValueError("adversary=True: the adversary sets the forces, give no points or DR")
        if chosen and (points is not None or domain_randomization or adversary):
            raise ValueError(
                "chosen=True: set_points gives the points, give no points, DR or adversary"
            )
        if modes is not None and (
            points is not None or domain_randomization or adversary or chosen
        ):
            raise ValueError("modes= replaces points, domain_randomization, adversary and chosen")
        self._wp, self._mjw, self._k = wp, mjw, kernels
        self.task, self.array = TWIN_TASKS[key], array
        self.resolved = resolve(key, uncertainty or default_set(key))
        self.box = self.resolved.box
        self.cpu = self.resolved.make_env(**env_kwargs)
        for spec in self.cpu.param_specs:
            if spec.name in self.box.names and spec.field in UNSUPPORTED_FIELDS:
                raise ValueError(f"parameter {spec.name!r}: {UNSUPPORTED_FIELDS[spec.field]}")
        self.num_envs = n = num_envs
        self.device = wp.get_device(device)
        self.max_episode_steps = max_episode_steps or get_task(key).max_episode_steps or 1000
        self.single_observation_space = self.cpu.observation_space
        self.single_action_space = self.cpu.action_space
        fresh = domain_randomization and pool == 0  # a point of the box per episode
        one = "adversary" if adversary else "chosen" if chosen else "random" if fresh else None
        self.world_modes = self._modes(modes, one or "nominal")
        self.adversary_dim = self._adversary("adversary" in self.world_modes)
        self.observation_space = gym.vector.utils.batch_space(self.single_observation_space, n)
        self.action_space = gym.vector.utils.batch_space(self.single_action_space, n)
        pool_from = seed if pool_seed is None else pool_seed
        self.fresh = "random" in self.world_modes
        dr = domain_randomization and not fresh
        self.pool_points = pool_points(self.box, n, points, dr, pool, pool_from)
        self.redraw = int(domain_randomization and not fresh)
        self.chosen = "chosen" in self.world_modes  # those worlds' points: ``set_points``
        self.formula = fill_formula(kernels.Formula(), self.cpu, self.task, self.max_episode_steps)
        self.values: Any = None  # the written worlds' points (``_build``: if any)
        self._build(nconmax, njmax)
        self._seed(seed)
        self._graph: Any = None

    # -- construction -----------------------------------------------------------------------
    def _modes(self, modes: Sequence[str] | None, one: str) -> tuple[str, ...]:
        """Each world's mode (``modes``, or ``one`` for all of them), checked."""
        if modes is None:
            return (one,) * self.num_envs
        modes = tuple(modes)
        if len(modes) != self.num_envs:
            raise ValueError(f"{len(modes)} modes for {self.num_envs} worlds: give one each")
        for mode in modes:
            if mode not in WORLD_MODES:
                raise ValueError(f"world mode {mode!r}; valid: {', '.join(WORLD_MODES)}")
        return modes

    def _adversary(self, on: bool) -> int:
        """With ``on``, the joint action space and the entries each parameter writes
        (``rrls.twin.adversary.probe``); the adversary's width."""
        if not on:
            return 0
        box = self.box
        agent = self.single_action_space
        self.single_action_space = gym.spaces.Box(
            np.concatenate([agent.low, -np.ones(box.dim)]).astype(np.float32),
            np.concatenate([agent.high, np.ones(box.dim)]).astype(np.float32),
            dtype=np.float32,
        )
        return box.dim

    def _build(self, nconmax: int, njmax: int) -> None:
        wp, mjw, n = self._wp, self._mjw, self.num_envs
        mjm = self.cpu.model
        self.nq, self.nv, self.nu = mjm.nq, mjm.nv, mjm.nu
        with wp.ScopedDevice(self.device):
            batch = {f: n for f in MODEL_FIELDS}
            self.m = mjw.put_model(mjm, batch_sizes=batch)
            self.m.opt.timestep = wp.zeros(n, dtype=float)
            self.m.opt.gravity = wp.zeros(n, dtype=wp.vec3)
            self.d = mjw.put_data(mjm, mujoco.MjData(mjm), nworld=n, nconmax=nconmax, njmax=njmax)
            targets = {f: getattr(self.m, f) for f in MODEL_FIELDS}
            targets |= {"timestep": self.m.opt.timestep, "gravity": self.m.opt.gravity}
            targets["xfrc_applied"] = self.d.xfrc_applied
            host = host_fields(self.cpu, self.box, self.pool_points)
            self.fields = [(_floats(targets[f], n), wp.array(host[f], dtype=float)) for f in host]
            self.field_names = list(host)  # the order of ``fields``
            for view, pool in self.fields:
                if view.shape[1] != pool.shape[1]:
                    raise RuntimeError(f"field sizes differ: {view.shape} vs {pool.shape}")
            self.qpos0 = wp.array(np.asarray(self.cpu.init_qpos, dtype=np.float32), dtype=float)
            self.obs = wp.zeros((n, self.single_observation_space.shape[0]), dtype=float)
            self.final_obs = wp.zeros_like(self.obs)
            self.reward = wp.zeros(n, dtype=float)
            self.terminated = wp.zeros(n, dtype=int)
            self.truncated = wp.zeros(n, dtype=int)
            self.done = wp.zeros(n, dtype=int)
            self.all = wp.ones(n, dtype=int)
            self.steps = wp.zeros(n, dtype=int)
            self.episode = wp.zeros(n, dtype=int)
            self.x_before = wp.zeros(n, dtype=float)
            self.point = wp.array(np.arange(n, dtype=np.int32) % len(self.pool_points), dtype=int)
            self.action = wp.zeros((n, self.nu), dtype=float)
            # the step's input: the action itself, or with an adversary the joint action
            self.joint = self.action
            if self.adversary_dim:
                self.joint = wp.zeros((n, self.nu + self.adversary_dim), dtype=float)
            modes = np.array(self.world_modes)
            mask = {m: wp.array((modes == m).astype(np.int32), dtype=int) for m in WORLD_MODES}
            self.drawn, self.pushed = mask["random"], mask["adversary"]
            written = modes != "nominal"
            self.written = wp.array(written.astype(np.int32), dtype=int)
            self.kept = mask["nominal"]
            self.mixed = bool(written.any() and not written.all())
            if written.any():  # points written on the device
                from rrls.twin.adversary import PointWrites

                views = {f: _floats(t, n) for f, t in targets.items()}
                self.writes = PointWrites(self.cpu, self.box, views)
                nominal = np.asarray(self.box.nominal, dtype=np.float32)  # until set_points
                self.values = wp.array(np.tile(nominal, (n, 1)), dtype=float)
            self.seeds = wp.zeros(n, dtype=int)

    def _seed(self, seed: int | Sequence[int]) -> None:
        """World ``w``'s stream: ``SeedSequence(seed, spawn_key=(w,))`` whatever the count, or
        ``SeedSequence(seed[w])`` for one seed per world (``K`` runs, one world each)."""
        if isinstance(seed, (int, np.integer)):
            seqs = [np.random.SeedSequence(int(seed), spawn_key=(w,)) for w in range(self.num_envs)]
        else:
            if len(seed) != self.num_envs:
                raise ValueError(f"{len(seed)} seeds for {self.num_envs} worlds: give one each")
            seqs = [np.random.SeedSequence(int(s)) for s in seed]
        words = [q.generate_state(1, np.uint32)[0] for q in seqs]
        self.seeds.assign(np.array(words, dtype=np.uint32).view(np.int32))
        self.episode.zero_()

    # -- the VectorEnv API --------------------------------------------------------------------
    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        if seed is not None:
            self._seed(seed)
        with self._wp.ScopedDevice(self.device):
            self._reset(self.all)
        return self._out(self.obs), {}

    def step(self, actions: Any):
        wp = self._wp
        with wp.ScopedDevice(self.device):
            self._actions(actions)
            if not self.device.is_cuda:
                self._advance()
            elif self._graph is None:  # the first step compiles; the second is captured
                self._advance()
                self._graph = False
            elif self._graph is False:
                with wp.ScopedCapture() as capture:
                    self._advance()
                self._graph = capture.graph
                wp.capture_launch(self._graph)
            else:
                wp.capture_launch(self._graph)
        info = {"final_obs": self._out(self.final_obs), "_final_obs": self._out(self.done, bool)}
        return (
            self._out(self.obs),
            self._out(self.reward),
            self._out(self.terminated, bool),
            self._out(self.truncated, bool),
            info,
        )

    def _advance(self) -> None:
        """One env step of every world, then the reset of those that ended: only kernel
        launches on fixed arrays, so on a GPU it is captured once in a CUDA graph."""
        wp, k, n = self._wp, self._k, self.num_envs
        action = self.action
        if self.adversary_dim:  # the protagonist's columns, then the adversary's point
            wp.launch(k.split_action, (n, self.nu), [self.joint, action])
            w = self.writes
            point = [self.joint, self.nu, w.low, w.span, self.pushed, self.values]
            wp.launch(k.adversary_point, (n, self.adversary_dim), point)
            self._write_points()
        wp.launch(k.begin_step, (n, self.nu), [action, self.d.qpos, self.d.ctrl, self.x_before])
        for _ in range(self.formula.frame_skip):
            self._mjw.step(self.m, self.d)
        if self.task.cfrc:
            self._mjw.rne_postconstraint(self.m, self.d)
        wp.launch(
            k.finish_step,
            n,
            [
                self.formula,
                self.d.qpos,
                self.d.qvel,
                self.d.cfrc_ext,
                action,
                self.x_before,
                self.m.opt.timestep,
                self.steps,
                self.reward,
                self.terminated,
                self.truncated,
                self.done,
            ],
        )
        wp.launch(
            k.observe,
            n,
            [self.formula, self.d.qpos, self.d.qvel, self.d.cfrc_ext, self.all, self.obs],
        )
        wp.copy(self.final_obs, self.obs)
        self._reset(self.done)

    def _reset(self, mask: Any) -> None:
        wp, k, n = self._wp, self._k, self.num_envs
        self._mjw.reset_data(self.m, self.d, reset=mask)
        if self.fresh:  # before reset_worlds counts the episode
            w = self.writes
            draw = [mask, self.drawn, self.seeds, self.episode, w.low, w.span, self.values]
            wp.launch(k.draw_point, n, draw)
        wp.launch(
            k.reset_worlds,
            n,
            [
                self.formula,
                mask,
                self.seeds,
                self.episode,
                self.qpos0,
                len(self.pool_points),
                self.redraw,
                self.d.qpos,
                self.d.qvel,
                self.steps,
                self.point,
            ],
        )
        for view, pool in self.fields:
            wp.launch(k.copy_point, view.shape, [mask, self.point, pool, view])
        if self.fresh or self.chosen:  # the world's own point again, over the nominal fields
            self._write_points()
        wp.launch(
            k.observe, n, [self.formula, self.d.qpos, self.d.qvel, self.d.cfrc_ext, mask, self.obs]
        )

    def _write_points(self) -> None:
        """The written worlds' points into their fields, the derived constants recomputed; in a
        mixed twin the nominal worlds' fields then as copied from CPU MuJoCo again (MuJoCo
        Warp's ``set_const`` derives every world's constants, in float32)."""
        self.writes.write(self.values, self.m, self.d, self.written)
        if self.mixed:
            for view, pool in self.fields:
                self._wp.launch(self._k.copy_point, view.shape, [self.kept, self.point, pool, view])

    def _actions(self, actions: Any) -> None:
        """Copy the actions into the twin's input array (on the device: a device copy)."""
        wp, shape = self._wp, self.joint.shape
        if type(actions).__module__.startswith("torch"):
            actions = wp.from_torch(actions.detach().float().contiguous())
        if isinstance(actions, wp.array):
            if actions.shape != shape:
                raise ValueError(f"actions have shape {actions.shape}; expected {shape}")
            wp.copy(self.joint, actions)
            return
        a = np.asarray(actions, dtype=np.float32)
        if a.shape != shape:
            raise ValueError(f"actions have shape {a.shape}; expected {shape}")
        self.joint.assign(a)

    def _out(self, a: Any, dtype: Any = None) -> Any:
        if self.array == "warp":
            return a
        if self.array == "torch":
            t = self._wp.to_torch(a)
            return t.bool() if dtype is bool else t
        out = a.numpy().copy()
        return out.astype(dtype) if dtype is not None else out

    def set_points(self, points: Any, first: int = 0) -> None:
        """``chosen`` worlds' points from now on, ``(rows, dim)`` over ``box.names`` for worlds
        ``first .. first + rows - 1`` (a device tensor or warp array: no host round trip; or host
        values), written into their fields with the derived constants recomputed, as
        ``set_params`` writes a CPU env's. A reset state does not depend on the point, so writing
        it just after a world's reset is the CPU's ``reset(options=point)`` (M2TD3: the point
        chosen as its episode begins)."""
        wp = self._wp
        if type(points).__module__.startswith("torch"):
            points = wp.from_torch(points.detach().float().contiguous())
        if not isinstance(points, wp.array):
            points = np.asarray(points, dtype=np.float32)
        rows = points.shape[0] if len(points.shape) == 2 else -1
        worlds = self.world_modes[first : first + rows] if first >= 0 and rows > 0 else ()
        if len(points.shape) != 2 or points.shape[1] != self.box.dim or len(worlds) != rows:
            raise ValueError(
                f"points have shape {tuple(points.shape)} from world {first}; expected (rows, "
                f"{self.box.dim}) within the twin's {self.num_envs} worlds"
            )
        if any(mode != "chosen" for mode in worlds):
            raise ValueError("set_points needs chosen worlds (chosen=True, or modes= 'chosen')")
        with wp.ScopedDevice(self.device):
            if not isinstance(points, wp.array):
                points = wp.array(points, dtype=float)
            dim = self.box.dim
            wp.copy(self.values, points, dest_offset=first * dim, count=rows * dim)
            self._write_points()

    # -- what a check or a log needs ----------------------------------------------------------
    def points(self) -> np.ndarray:
        """Each world's current point, ``(num_envs, dim)`` over ``box.names`` (a host copy)."""
        pooled = self.pool_points[self.point.numpy()]
        if self.values is None:
            return pooled
        written = (np.array(self.world_modes) != "nominal")[:, None]
        return np.where(written, self.values.numpy().astype(np.float64), pooled)

    def state(self) -> tuple[np.ndarray, np.ndarray]:
        """Each world's ``(qpos, qvel)`` (host copies, float32)."""
        return self.d.qpos.numpy().copy(), self.d.qvel.numpy().copy()

    def set_state(self, qpos: np.ndarray, qvel: np.ndarray) -> None:
        """Put every world at a state (the episode's step count is kept)."""
        self.d.qpos.assign(np.asarray(qpos, dtype=np.float32))
        self.d.qvel.assign(np.asarray(qvel, dtype=np.float32))

    def episodes(self) -> np.ndarray:
        """Each world's episode count, the episode in progress included (a host copy): with
        the world's seed it fixes that episode's first state and DR point."""
        return self.episode.numpy().copy()

    def restart(self, episodes: np.ndarray) -> Any:
        """Reset every world to the first state and point of its episode number
        ``episodes[w]`` (counted as ``episodes()`` counts): a resumed run starts the episode it
        was in again. Returns the observations, as ``reset`` does."""
        counts = np.asarray(episodes, dtype=np.int32)
        if counts.shape != (self.num_envs,) or (counts < 1).any():
            raise ValueError(f"episodes must be {self.num_envs} counts >= 1, got {counts.tolist()}")
        self.episode.assign(counts - 1)
        with self._wp.ScopedDevice(self.device):
            self._reset(self.all)
        return self._out(self.obs)

    def put_world(self, w: int, env: Any) -> None:
        """World ``w`` becomes a copy of CPU env ``env`` as it stands: its model fields at its
        point (the derived constants included), its applied forces, its ``(qpos, qvel)``, a
        fresh step count and solver warm start. What ``rrls train --simulator warp`` does at
        every episode's start, after resetting the CPU env with the run's seed and options, so
        a twin episode begins where the CPU env's would, at the point its learner chose."""
        wp = self._wp
        if not 0 <= w < self.num_envs:
            raise ValueError(f"world {w} out of range; this twin has {self.num_envs}")
        data = env.unwrapped.data
        host = model_fields(env.unwrapped.model, data)
        with wp.ScopedDevice(self.device):
            mask = np.zeros(self.num_envs, dtype=np.int32)
            mask[w] = 1
            self._mjw.reset_data(self.m, self.d, reset=wp.array(mask, dtype=int))
            for (view, _), name in zip(self.fields, self.field_names):
                row = np.asarray(host[name], dtype=np.float32).ravel()
                width = view.shape[1]
                wp.copy(view, wp.array(row, dtype=float), dest_offset=w * width, count=width)
            for target, value in ((self.d.qpos, data.qpos), (self.d.qvel, data.qvel)):
                row = np.asarray(value, dtype=np.float32)
                wp.copy(
                    target, wp.array(row, dtype=float), dest_offset=w * len(row), count=len(row)
                )
            steps = self.steps.numpy()
            steps[w] = 0
            self.steps.assign(steps)

    def close(self, **kwargs: Any) -> None:
        self.cpu.close()


__all__ = ["WORLD_MODES", "WarpTwin", "default_set"]
