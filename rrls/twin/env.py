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
model.

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
from rrls.uncertainty import UncertaintySet

#: MuJoCo Warp's batched model fields that rrls's kinds write or ``mj_setConst`` derives
MODEL_FIELDS = (
    "body_mass",
    "body_inertia",
    "body_ipos",
    "body_subtreemass",
    "body_invweight0",
    "geom_friction",
    "dof_damping",
    "dof_armature",
    "dof_frictionloss",
    "dof_invweight0",
    "actuator_gear",
    "actuator_acc0",
)
ARRAYS = ("numpy", "torch", "warp")
POOL_KEY = 2**31 - 1  # the pool's stream: a spawn key no world uses


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
        self.adversary_dim = self._adversary(adversary)
        self.observation_space = gym.vector.utils.batch_space(self.single_observation_space, n)
        self.action_space = gym.vector.utils.batch_space(self.single_action_space, n)
        pool_from = seed if pool_seed is None else pool_seed
        self.fresh = domain_randomization and pool == 0  # a point of the box per episode
        self.pool_points = self._pool(
            points, domain_randomization and not self.fresh, pool, pool_from
        )
        self.redraw = int(domain_randomization and not self.fresh)
        self.chosen = chosen  # each world's point is the caller's (``set_points``)
        self.formula = fill_formula(kernels.Formula(), self.cpu, self.task, self.max_episode_steps)
        self._build(nconmax, njmax)
        self._seed(seed)
        self._graph: Any = None

    # -- construction -----------------------------------------------------------------------
    def _pool(self, points: Any, dr: bool, size: int, seed: Any) -> np.ndarray:
        """The points the worlds draw from: the given ones (one per world), a seeded uniform
        pool of the set (DR), or the nominal point."""
        dim = self.box.dim
        if points is not None:
            pts = np.asarray(points, dtype=np.float64)
            if pts.shape != (self.num_envs, dim):
                raise ValueError(
                    f"points has shape {pts.shape}; expected ({self.num_envs}, {dim}): one row "
                    f"per world over {list(self.box.names)}"
                )
            for row in pts:
                if not self.box.contains(row):
                    raise ValueError(f"point {row.tolist()} lies outside {self.box.label}")
            return pts
        if dr:
            if not isinstance(size, int) or size < 1:
                raise ValueError(
                    f"pool must be a positive integer (0: a point of the box per episode), "
                    f"got {size!r}"
                )
            entropy = int(seed) if isinstance(seed, (int, np.integer)) else [int(x) for x in seed]
            rng = np.random.default_rng(np.random.SeedSequence(entropy, spawn_key=(POOL_KEY,)))
            return np.asarray(self.box.sample(rng, size), dtype=np.float64).reshape(size, dim)
        return np.asarray(self.box.nominal, dtype=np.float64).reshape(1, dim)

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

    def _host_fields(self, pts: np.ndarray) -> dict[str, np.ndarray]:
        """Each point's packed fields, as a CPU model at that point holds them."""
        cpu, names = self.cpu, self.box.names
        rows: dict[str, list[np.ndarray]] = {}
        for p in pts:
            cpu.set_params(**dict(zip(names, p.tolist(), strict=True)))
            got = {f: getattr(cpu.model, f) for f in MODEL_FIELDS}
            got["timestep"] = np.array([cpu.model.opt.timestep])
            got["gravity"] = np.array(cpu.model.opt.gravity)
            got["xfrc_applied"] = np.array(cpu.data.xfrc_applied)
            for f, v in got.items():
                rows.setdefault(f, []).append(np.asarray(v, dtype=np.float32).ravel())
        cpu.reset_params()
        return {f: np.stack(v) for f, v in rows.items()}

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
            host = self._host_fields(self.pool_points)
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
            if self.adversary_dim or self.fresh or self.chosen:  # points written on the device
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
            point = [self.joint, self.nu, w.low, w.span, self.values]
            wp.launch(k.adversary_point, (n, self.adversary_dim), point)
            w.write(self.values, self.m, self.d)
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
            draw = [mask, self.seeds, self.episode, w.low, w.span, self.values]
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
            self.writes.write(self.values, self.m, self.d)
        wp.launch(
            k.observe, n, [self.formula, self.d.qpos, self.d.qvel, self.d.cfrc_ext, mask, self.obs]
        )

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

    def set_points(self, points: Any) -> None:
        """``chosen=True``: each world's point from now on, ``(num_envs, dim)`` over ``box.names``
        (a device tensor or warp array: no host round trip; or host values), written into its
        fields with the derived constants recomputed, as ``set_params`` writes a CPU env's. A
        reset state does not depend on the point, so writing it just after a world's reset is
        the CPU's ``reset(options=point)`` (M2TD3: the point chosen as its episode begins)."""
        wp = self._wp
        if not self.chosen:
            raise ValueError("set_points needs a twin built with chosen=True")
        if type(points).__module__.startswith("torch"):
            points = wp.from_torch(points.detach().float().contiguous())
        with wp.ScopedDevice(self.device):
            if isinstance(points, wp.array):
                if points.shape != self.values.shape:
                    raise ValueError(
                        f"points have shape {points.shape}; expected {self.values.shape}"
                    )
                wp.copy(self.values, points)
            else:
                host = np.asarray(points, dtype=np.float32)
                if host.shape != self.values.shape:
                    raise ValueError(
                        f"points have shape {host.shape}; expected {self.values.shape}"
                    )
                self.values.assign(host)
            self.writes.write(self.values, self.m, self.d)

    # -- what a check or a log needs ----------------------------------------------------------
    def points(self) -> np.ndarray:
        """Each world's current point, ``(num_envs, dim)`` over ``box.names`` (a host copy)."""
        if self.fresh or self.adversary_dim or self.chosen:
            return self.values.numpy().astype(np.float64)
        return self.pool_points[self.point.numpy()]

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
        model, data = env.unwrapped.model, env.unwrapped.data
        host = {f: getattr(model, f) for f in MODEL_FIELDS}
        host["timestep"] = np.array([model.opt.timestep])
        host["gravity"] = np.array(model.opt.gravity)
        host["xfrc_applied"] = np.array(data.xfrc_applied)
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


__all__ = ["MODEL_FIELDS", "WarpTwin", "default_set"]
