"""The one generic robust environment, driven by a task's parameter table.

:class:`ModifiedParamsMixin` sits in front of a Gymnasium v5 MuJoCo env class in the MRO
(``class RobustHopper(ModifiedParamsMixin, HopperEnv)``). It adds ``set_params``/``get_params``
for the rows of ``param_specs`` and touches nothing else, so at nominal parameters the env is
bit-identical to ``gym.make("Hopper-v5")``.
"""

from __future__ import annotations

import contextlib
import copy
import hashlib
from collections.abc import Callable, Iterable, Iterator
from typing import Any, ClassVar

import mujoco
import numpy as np
from gymnasium.utils import EzPickle

from rrls.envs.paper import NO_SETCONST
from rrls.params import SETCONST_FIELDS, Parameter, kind_fields
from rrls.tasks import TaskSpec

_FORCES = "xfrc_applied"
#: compiled models by (XML file, a hash of its text, offscreen width and height): compiling a
#: model is ~3 ms an env (an evaluation builds 64 lanes: ~0.2 s), copying one ~0.15 ms; each env
#: gets its own copy, identical to a fresh compile. (Files the XML includes are not hashed: an
#: edit to one while a process runs is not seen by that process.)
_MODELS: dict[tuple[str, str, int, int], mujoco.MjModel] = {}
_FRICTION = frozenset({"geom_friction", "body_friction"})
#: kinds always reported in ``info`` (the original code's); others once they are set
_INFO_FIELDS = frozenset({"body_mass", "geom_friction", "xfrc_applied"})
#: model arrays a parameter may write: saved when the env is built, restored by reset_params
SAVED_FIELDS = (
    "body_mass",
    "body_inertia",
    "body_ipos",
    "geom_friction",
    "dof_damping",
    "dof_armature",
    "dof_frictionloss",
    "actuator_gear",
)


#: the environment variable that silences the deprecations of Gymnasium's XML (rrls's commands)
QUIET_XML_DEPRECATIONS = "RRLS_QUIET_XML_DEPRECATIONS"


@contextlib.contextmanager
def mujoco_warnings_to_python() -> Iterator[None]:
    """Route MuJoCo's warnings to Python's ``warnings`` instead of ``MUJOCO_LOG.TXT``.

    MuJoCo's default handler appends every warning (e.g. the deprecated ``settotalmass`` in
    HalfCheetah's XML) to a file in the working directory; we only swap the handler while we
    compile a model, so a user's own handler stays in place otherwise. With
    ``RRLS_QUIET_XML_DEPRECATIONS=1`` in the environment (what rrls's own commands set, so their
    worker processes inherit it) the deprecations of Gymnasium's shipped XML files are dropped:
    a user's own code still sees them.
    """
    import os
    import warnings

    def warn(msg: str) -> None:
        quiet = os.environ.get(QUIET_XML_DEPRECATIONS) == "1"
        if not (quiet and "is deprecated" in msg and "compiler attribute" in msg):
            warnings.warn(f"MuJoCo: {msg}", stacklevel=3)

    previous = mujoco.get_mju_user_warning()
    mujoco.set_mju_user_warning(warn)
    try:
        yield
    finally:
        mujoco.set_mju_user_warning(previous)


class ModifiedParamsMixin:
    """Adds the ``ModifiedParamsEnv`` interface to a Gymnasium MuJoCo env.

    Parameters are set by constructor keywords, :meth:`set_params` (partial updates) or
    ``reset(options={...})``; :meth:`get_params` returns the original code's kinds (masses,
    ``worldfriction``, forces), ``get_params(kinds="all")`` every parameter. ``info`` at reset
    and at every step carries the current values of the original code's kinds (masses,
    ``worldfriction``, forces) and of every parameter set since the model was built: copying
    all ~30-140 rows into every step's ``info`` would cost up to 10 % of a step.
    ``scale_inertia=True`` scales a body's inertia with its mass (default: the paper's
    semantics, mass only).
    """

    task: ClassVar[TaskSpec]
    param_specs: ClassVar[tuple[Parameter, ...]]
    #: built on the paper's physics (the original code's env and writes: rrls.envs.paper)
    paper: ClassVar[bool] = False
    #: the class of the same task and family on the paper's physics (None: there is none)
    paper_twin: ClassVar[Callable[[], type] | None] = None

    # -- construction -------------------------------------------------------------------------
    def __new__(cls, *args: Any, **kwargs: Any) -> Any:
        """``paper=True`` builds the class's twin on the paper's physics instead."""
        if kwargs.get("paper") and not cls.paper:
            if cls.paper_twin is None:
                raise ValueError(
                    f"{cls.__name__} has no paper physics (paper=True is for the paper's six "
                    "tasks: the v5 envs their code built)"
                )
            twin = cls.paper_twin()
            obj = twin.__new__(twin, *args, **kwargs)
            obj.__init__(*args, **kwargs)  # not a subclass of cls: Python would skip __init__
            return obj
        return super().__new__(cls)

    def __init__(self, *, scale_inertia: bool = False, paper: bool = False, **kwargs: Any) -> None:
        params = {k: kwargs.pop(k) for k in list(kwargs) if k in self._names()}
        try:
            super().__init__(**{**self.task.env_kwargs, **kwargs})  # the Gymnasium env
        except TypeError as exc:
            raise TypeError(
                f"{exc}. {type(self).__name__} takes the physical parameters "
                f"{', '.join(self.param_names())} and the keywords of "
                f"{self.task.v5_id or self.task.base_class().__name__}"
            ) from None
        # EzPickle records *our* constructor arguments, so copies rebuild a robust env.
        physics = {"paper": True} if self.paper else {}
        EzPickle.__init__(self, scale_inertia=scale_inertia, **physics, **params, **kwargs)
        self.scale_inertia = bool(scale_inertia)
        model = self.model
        self._rows = {s.name: (s, s.resolve(model)) for s in self.param_specs}
        # the paper's physics writes masses as the original did: body_mass alone (rrls.envs.paper)
        self._setconst = SETCONST_FIELDS - NO_SETCONST if self.paper else SETCONST_FIELDS
        if self.scale_inertia:  # a scaled inertia needs its derived constants, paper or not
            self._setconst = SETCONST_FIELDS
        self._saved = {f: getattr(model, f).copy() for f in SAVED_FIELDS}
        self._mass0 = self._saved["body_mass"]
        self._inertia0 = self._saved["body_inertia"]
        self._ipos0 = self._saved["body_ipos"]
        self._gravity0 = model.opt.gravity.copy()
        self._timestep0 = float(model.opt.timestep)
        self._viscosity0 = float(model.opt.viscosity)
        # mj_setConst uses its MjData as scratch space (it overwrites qpos): never the live one.
        self._scratch = mujoco.MjData(model)
        self._friction_rows = [s for s in self.param_specs if s.field in _FRICTION]
        self._values: dict[str, float] = {s.name: self._read(s) for s in self.param_specs}
        self._info = self._info_values()
        self._overrides: dict[str, float] = {}
        self._init_params: dict[str, float] = {}
        if params:
            self.set_params(**params)
        self._init_params = dict(self._overrides)

    def _initialize_simulation(self):  # Gymnasium's signature
        """Gymnasium's, compiling each XML file once per process: later envs copy the model."""
        with open(self.fullpath, "rb") as f:
            text = hashlib.blake2b(f.read(), digest_size=16).hexdigest()
        key = (self.fullpath, text, self.width, self.height)
        if key not in _MODELS:
            with mujoco_warnings_to_python():
                model, data = super()._initialize_simulation()
            _MODELS[key] = copy.copy(model)  # before this env changes its own
            return model, data
        model = copy.copy(_MODELS[key])
        return model, mujoco.MjData(model)

    @classmethod
    def _names(cls) -> dict[str, str]:
        """Every accepted name (aliases included) -> canonical name."""
        names = {s.name: s.name for s in cls.param_specs}
        names.update({a: s.name for s in cls.param_specs for a in s.aliases})
        return names

    @classmethod
    def param_names(cls) -> tuple[str, ...]:
        """The canonical parameter names, in table order."""
        return tuple(s.name for s in cls.param_specs)

    # -- the ModifiedParamsEnv interface ------------------------------------------------------
    def get_params(self, kinds: str | Iterable[str] | None = None) -> dict[str, float]:
        """Parameters and their current values: by default the original code's kinds (masses,
        ``worldfriction``, forces), so code written for it runs unchanged (setting every value
        it returns to 1 stays valid); ``kinds="all"`` every parameter, or the kinds named
        (``"damping"``, ``("mass", "gear")``: :data:`rrls.params.KINDS`).

        On the planar force envs the original's ``<part>force_z`` is listed too, by default (an
        alias of ``_y``: both push along the vertical axis). A task with none of the original's
        kinds (a user's task of joint rows only) returns every parameter by default.
        """
        fields = kind_fields(kinds)
        values = self._values
        if fields is None:
            return dict(values)
        original = kinds is None or kinds == "original"
        out: dict[str, float] = {}
        for spec in self.param_specs:
            if spec.field in fields:
                out[spec.name] = values[spec.name]
                if original:  # the original's spelling of every row
                    for alias in spec.aliases:
                        out[alias] = values[spec.name]
        return out if out or not original else dict(values)

    def set_params(self, **params: float) -> None:
        """Set some parameters; the others keep their values.

        Everything is validated before anything is written, so bad input changes nothing.
        Values are written in the order given: where two parameters write the same geoms
        (``worldfriction`` and ``footfriction``), the later one wins for those geoms, and
        ``get_params`` reports what the model holds.
        """
        updates = self._validate(params)
        set_const = friction = False
        for name, value in updates.items():
            spec, idx = self._rows[name]
            self._write(spec, idx, value)
            set_const |= spec.field in self._setconst
            friction |= spec.field in _FRICTION
        if set_const:
            try:
                mujoco.mj_setConst(self.model, self._scratch)
            except mujoco.FatalError as err:  # put the model back: a refused call changes nothing
                for name in reversed(updates):
                    spec, idx = self._rows[name]
                    self._write(spec, idx, self._values[name])
                mujoco.mj_setConst(self.model, self._scratch)
                raise ValueError(f"MuJoCo refused {updates}: {err}") from None
        self._values.update(updates)
        info = self._info
        if friction:  # rows sharing geoms: report what the model now holds
            for spec in self._friction_rows:
                self._values[spec.name] = value = self._read(spec)
                if spec.name in info:
                    info[spec.name] = value
        for name in updates:
            info[name] = self._values[name]
            for alias in self._rows[name][0].aliases:  # the original's spelling too (_z)
                info[alias] = info[name]
        for name, value in updates.items():  # latest last, so copies replay in the same order
            self._overrides.pop(name, None)
            self._overrides[name] = value

    def reset_params(self) -> None:
        """Restore the model exactly as built (nominal, or the constructor's parameters).

        Unlike ``set_params(**nominal)`` this also restores per-geom frictions (e.g. Hopper's
        foot friction 2.0, which ``worldfriction`` overwrites).
        """
        model = self.model
        for name, saved in self._saved.items():
            getattr(model, name)[:] = saved
        model.opt.gravity[:] = self._gravity0
        model.opt.timestep = self._timestep0
        model.opt.viscosity = self._viscosity0
        self.data.xfrc_applied[:] = 0.0
        mujoco.mj_setConst(model, self._scratch)
        self._values = {s.name: self._read(s) for s in self.param_specs}
        self._info = self._info_values()
        self._overrides = {}
        if self._init_params:
            self.set_params(**self._init_params)

    def _info_values(self) -> dict[str, float]:
        """The original code's kinds, as ``get_params()`` names them (planar ``_z`` included)."""
        info = {}
        for s in self.param_specs:
            if s.field in _INFO_FIELDS:
                info[s.name] = self._values[s.name]
                for alias in s.aliases:
                    info[alias] = info[s.name]
        return info

    def _validate(self, params: dict[str, Any]) -> dict[str, float]:
        names = self._names()
        unknown = [k for k in params if k not in names]
        if unknown:
            raise ValueError(
                f"unknown parameter(s) {unknown} for {type(self).__name__}; "
                f"valid names: {', '.join(self.param_names())}"
            )
        updates: dict[str, float] = {}
        for key, value in params.items():
            if value is None:  # the original code's "leave unchanged"
                continue
            spec = self._rows[names[key]][0]
            if isinstance(value, np.ndarray) and value.size == 1:
                value = value.item()
            problem = spec.check(value)
            if problem:
                raise ValueError(problem)
            updates[spec.name] = float(value)
        return updates

    def _read(self, spec: Parameter) -> float:
        idx = self._rows[spec.name][1]
        model, field = self.model, spec.field
        if field == "body_mass":
            return float(model.body_mass[idx[0]])
        if field == "geom_friction":
            if spec.target != "*":
                return float(model.geom_friction[idx[0], 0])
            # every geom: the floor's (first world geom), the paper's reference
            floor = np.flatnonzero(model.geom_bodyid == 0)[0]
            return float(model.geom_friction[floor, 0])
        if field == "body_friction":
            return float(model.geom_friction[idx[0], 0])
        if field == "body_ipos":
            b, k = idx[0], spec.component
            return float(model.body_ipos[b, k] - self._ipos0[b, k])
        if field in ("dof_damping", "dof_armature", "dof_frictionloss"):
            return float(getattr(model, field)[idx[0]])
        if field == "actuator_gear":
            return float(model.actuator_gear[idx[0], 0])
        if field == "opt_gravity":
            return float(-model.opt.gravity[2])
        if field == "opt_timestep":
            return float(model.opt.timestep)
        if field == "opt_viscosity":
            return float(model.opt.viscosity)
        return float(self.data.xfrc_applied[idx[0], spec.component])

    def _write(self, spec: Parameter, idx: np.ndarray, value: float) -> None:
        model, field = self.model, spec.field
        if field == "body_mass":
            b = idx[0]
            model.body_mass[b] = value
            if self.scale_inertia:
                model.body_inertia[b] = self._inertia0[b] * (value / self._mass0[b])
        elif field in ("geom_friction", "body_friction"):
            model.geom_friction[idx, 0] = value
        elif field == "body_ipos":
            b, k = idx[0], spec.component
            model.body_ipos[b, k] = self._ipos0[b, k] + value
        elif field in ("dof_damping", "dof_armature", "dof_frictionloss"):
            getattr(model, field)[idx[0]] = value
        elif field == "actuator_gear":
            model.actuator_gear[idx[0], 0] = value
        elif field == "opt_gravity":
            model.opt.gravity[2] = -value
        elif field == "opt_timestep":
            model.opt.timestep = value
        elif field == "opt_viscosity":
            model.opt.viscosity = value
        else:
            self.data.xfrc_applied[idx[0], spec.component] = value

    # -- Gymnasium hooks ----------------------------------------------------------------------
    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        """``options`` may hold parameters to set before the episode starts."""
        if options:
            self.set_params(**options)
        obs, info = super().reset(seed=seed, options=options)
        info.update(self._info)
        return obs, info

    def reset_model(self):  # Gymnasium's signature
        # mj_resetData zeroes xfrc_applied: put the forces back so they act from the first step.
        for name, (spec, idx) in self._rows.items():
            if spec.field == _FORCES:
                self.data.xfrc_applied[idx[0], spec.component] = self._values[name]
        return super().reset_model()

    def step(self, action):  # Gymnasium's signature
        obs, reward, terminated, truncated, info = super().step(action)
        info.update(self._info)
        return obs, reward, terminated, truncated, info

    # -- copies -------------------------------------------------------------------------------
    def __getstate__(self) -> dict[str, Any]:
        """Constructor args + parameters + the whole MjData (so copies continue bit-identically)."""
        return {
            "ezpickle": EzPickle.__getstate__(self),
            "overrides": dict(self._overrides),
            "data": self.data,
            "np_random": self._np_random,
            "np_random_seed": self._np_random_seed,
            "spec": self.spec,
        }

    def __setstate__(self, state: dict[str, Any]) -> None:
        EzPickle.__setstate__(self, state["ezpickle"])
        self.set_params(**state["overrides"])
        mujoco.mj_copyData(self.data, self.model, state["data"])
        self._np_random = state["np_random"]
        self._np_random_seed = state["np_random_seed"]
        self.spec = state["spec"]


__all__ = ["SAVED_FIELDS", "ModifiedParamsMixin", "mujoco_warnings_to_python"]
