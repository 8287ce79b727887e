"""The task registry: :func:`register_task` turns a Gymnasium MuJoCo env into an rrls task.

A task is data: which env it is built on, its parameter table (:class:`~rrls.params.Parameter`
rows naming bodies, geoms, joints and actuators), its force table and its uncertainty sets.
Registering it checks every row against the compiled model (a bad name fails here, listing the
valid ones), stores it in :data:`TASKS` and registers its Gymnasium ids; the env classes
``Robust<Name>``/``Force<Name>`` are built from it on first use (:mod:`rrls.envs`). The
built-in tasks (:mod:`rrls.tasks`) are declared through this same function.

>>> import gymnasium as gym
>>> from rrls import register_task
>>> from rrls.registry import unregister_task
>>> from rrls.params import mass_params
>>> spec = register_task(
...     "mydoublependulum",
...     "InvertedDoublePendulum-v5",
...     name="MyDoublePendulum",  # classes RobustMyDoublePendulum, ForceMyDoublePendulum
...     params=mass_params({"cart": "cart", "pole": "pole", "pole2": "pole2"}),
...     sets={"2d": {"polemass": (1.0, 10.0), "pole2mass": (1.0, 10.0)}},
... )
>>> env = gym.make("rrls/robust-mydoublependulum-v0")
>>> env.get_params()["pole2mass"] == float(env.unwrapped.model.body_mass[3])
True
>>> unregister_task("mydoublependulum")  # tasks live for the process; this one goes now

Third-party packages make their tasks visible to the ``rrls`` command (and to every process it
starts) with an entry point in the ``rrls.tasks`` group naming a function that calls
:func:`register_task` (or a module that does so when imported)::

    [project.entry-points."rrls.tasks"]
    mytasks = "mypackage.tasks:register"
"""

from __future__ import annotations

import re
import warnings
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

from gymnasium.envs.registration import registry

from rrls.gym_ids import register_ids, task_ids, unregister_ids
from rrls.params import Parameter, force_params
from rrls.uncertainty import UncertaintySet

Bounds = dict[str, tuple[float, float]]

#: entry point group scanned for third-party task packages
ENTRY_POINT_GROUP = "rrls.tasks"
#: episode length of a task whose env id declares none
MAX_EPISODE_STEPS = 1000
#: adversary strength of the ``probabilistic-action-robust`` ids (NR-MDP)
FAMILIES = ("robust", "force")


@dataclass(frozen=True)
class TaskSpec:
    """One task as data (see :func:`register_task`)."""

    key: str  #: short name used in ids and the CLI: "hopper"
    name: str  #: class-name stem: "Hopper" -> RobustHopper, ForceHopper
    v5_id: str | None  #: the Gymnasium id it is built on (None: built from ``env_class``)
    planar: bool  #: every joint moves in the world x-z plane (forces' ``_y`` is vertical)
    params: tuple[Parameter, ...]  #: robust env parameters (masses, friction, ...)
    forces: tuple[Parameter, ...]  #: force env parameters
    sets: dict[str, Bounds] = field(default_factory=dict)  #: "1d", "2d", "3d", "rarl"
    #: env family of each set: "robust" (parameters of ``params``) or "force" (of ``forces``)
    families: dict[str, str] = field(default_factory=dict)
    #: the Gymnasium env class (None: loaded from ``v5_id``'s entry point on first use)
    env_class: type | None = None
    #: keywords passed to the Gymnasium env class (the id's own kwargs by default)
    env_kwargs: dict[str, Any] = field(default_factory=dict)
    max_episode_steps: int = MAX_EPISODE_STEPS
    aliases: tuple[str, ...] = ()
    #: the Gymnasium id of the paper's physics (the env the original code built), for
    #: ``paper=True``; None: no such physics
    paper_id: str | None = None

    @property
    def env_id(self) -> str | None:
        """The Gymnasium id the task is built on (alias of ``v5_id``)."""
        return self.v5_id

    def base_class(self, paper: bool = False) -> type:
        """The Gymnasium env class the robust and force classes extend (``paper``: the env the
        paper's code ran)."""
        if paper:
            if self.paper_id is None:
                raise ValueError(
                    f"task {self.key!r} has no paper physics (paper=True is for the paper's "
                    "six tasks: the v5 envs their code built)"
                )
            env_id = self.paper_id
        elif self.env_class is not None:
            return self.env_class
        else:
            env_id = self.v5_id
        from gymnasium.envs.registration import load_env_creator

        creator = registry[env_id].entry_point
        cls = load_env_creator(creator) if isinstance(creator, str) else creator
        if not isinstance(cls, type):
            raise TypeError(f"{env_id}'s entry point is not a class: {cls!r}")
        return cls

    def family_of(self, names: tuple[str, ...] | list[str]) -> str:
        """The family whose parameter table holds every name (``"robust"`` if there are none)."""
        for family, specs in (("robust", self.params), ("force", self.forces)):
            valid = {s.name for s in specs} | {a for s in specs for a in s.aliases}
            if all(n in valid for n in names):
                return family
        robust = ", ".join(s.name for s in self.params)
        forces = ", ".join(s.name for s in self.forces)
        raise ValueError(
            f"parameters {list(names)} are not all of one family of task {self.key!r}; "
            f"robust parameters: {robust}; force parameters: {forces}"
        )

    def specs(self, family: str) -> tuple[Parameter, ...]:
        return self.params if family == "robust" else self.forces


#: every registered task, by key (the built-in ones and the users')
TASKS: dict[str, TaskSpec] = {}
#: accepted spellings of the task keys (the CLI and ``evaluate`` take any of them)
TASK_ALIASES: dict[str, str] = {}
#: the keys of the tasks rrls ships (filled by :mod:`rrls.tasks`): never replaced
BUILTIN_TASKS: set[str] = set()

_plugins_loaded = False


def _normalise(key: str) -> str:
    return key.lower().replace("-", "").replace(" ", "")


def get_task(key: str) -> TaskSpec:
    """The task spec of ``key`` (``"hopper"``, ``"walker"``, ...), with a clear error.

    An unknown key first loads the ``rrls.tasks`` entry points (once), so tasks of installed
    packages are found in any process, including the ones the CLI spawns.
    """
    if not isinstance(key, str):
        raise ValueError(f"task must be a string, got {key!r}")
    k = _normalise(key)
    k = TASK_ALIASES.get(k, k)
    if k not in TASKS and load_task_plugins():
        k = TASK_ALIASES.get(_normalise(key), _normalise(key))
    if k not in TASKS:
        raise ValueError(f"unknown task {key!r}; valid tasks: {', '.join(TASKS)}")
    return TASKS[k]


def load_task_plugins() -> bool:
    """Load the ``rrls.tasks`` entry points once; True if this call loaded any.

    Each entry point names a callable (called with no argument) or a module (imported); either
    registers its tasks with :func:`register_task`. A failing plugin is reported as a warning
    naming it, and the others still load.
    """
    global _plugins_loaded
    if _plugins_loaded:
        return False
    _plugins_loaded = True
    from importlib.metadata import entry_points

    loaded = False
    for ep in entry_points(group=ENTRY_POINT_GROUP):
        try:
            obj = ep.load()
            if callable(obj):
                obj()
        except Exception as err:  # noqa: BLE001 - a broken third-party package must not break rrls
            warnings.warn(
                f"rrls: task plugin {ep.name!r} ({ep.value}) failed to load: "
                f"{type(err).__name__}: {err}",
                stacklevel=2,
            )
            continue
        loaded = True
    return loaded


# -- registration ---------------------------------------------------------------------------------
_KEY = re.compile(r"[a-z][a-z0-9]*\Z")
_SET = re.compile(r"[a-z0-9][a-z0-9_]*\Z")


#: called with a task's key whenever it is registered, replaced or unregistered (``rrls.envs``
#: keeps its ``Robust<Task>``/``Force<Task>`` attributes in step with the table)
_LISTENERS: list[Callable[[str], None]] = []


def on_change(listener: Callable[[str], None]) -> None:
    """Call ``listener(key)`` after every change of the task table."""
    _LISTENERS.append(listener)


def _changed(key: str) -> None:
    for listener in _LISTENERS:
        listener(key)


def register_task(
    key: str,
    env: str | type,
    *,
    params: Sequence[Parameter] = (),
    sets: Mapping[str, Mapping[str, tuple[float, float]]] | None = None,
    forces: Sequence[Parameter] | None = None,
    name: str | None = None,
    planar: bool = False,
    env_kwargs: Mapping[str, Any] | None = None,
    max_episode_steps: int | None = None,
    aliases: Sequence[str] = (),
    paper_env: str | None = None,
    check: bool = True,
    replace: bool = False,
) -> TaskSpec:
    """Make a Gymnasium MuJoCo env an rrls task; returns its :class:`TaskSpec`.

    ``key``: lower-case letters and digits, used in ids (``rrls/robust-<key>-v0``) and the CLI.
    ``env``: a Gymnasium id (``"Swimmer-v5"``) or a ``MujocoEnv`` subclass. ``params``: the
    robust env's :class:`Parameter` rows (see :mod:`rrls.params` for ``mass_params``,
    ``physics_params``, ...). ``forces``: the force env's rows (default: a force on the body of
    every ``body_mass`` row, ``<part>force_x/_y/_z``). ``sets``: ``{set name: {parameter:
    (low, high)}}``; each set's env family is found from the tables (a set mixing robust
    parameters and forces is refused). ``name``: the class-name stem (default from the id or
    class: ``Swimmer`` -> ``RobustSwimmer``). ``planar``: every joint moves in the world x-z
    plane (``<part>force_y`` is then vertical). ``env_kwargs``: keywords of the env class.
    ``max_episode_steps``: default from the id, else 1000. ``paper_env``: the Gymnasium id of
    the env the original code built, that ``paper=True`` builds (the paper's tasks: v5 ids).

    With ``check`` (the default) the model is compiled once and every row's body, geom, joint or
    actuator is looked up in it: a bad declaration raises a ``ValueError`` listing the valid
    names, and nothing is registered. Nominal values are never declared: they are read from the
    model. Registering an identical task again is a no-op; a different one under a used key
    needs ``replace=True``.

    Registers ``rrls/robust-<key>-v0``, ``rrls/force-<key>-v0`` (if there are forces), for each
    robust set ``rrls/robust-<key>-adversarial-<set>-v0`` and
    ``rrls/robust-<key>-domain-randomization-<set>-v0``, for a force set
    ``rrls/robust-<key>-adversarial-forces-v0``, and ``rrls/probabilistic-action-robust-<key>-v0``.
    """
    spec = _build_spec(
        key, env, params, sets, forces, name, planar, env_kwargs, max_episode_steps, aliases
    )
    if paper_env is not None:
        if paper_env not in registry:
            raise ValueError(f"no Gymnasium env {paper_env!r} is registered")
        spec = TaskSpec(**{**spec.__dict__, "paper_id": paper_env})
    owner = TASK_ALIASES.get(spec.key)
    if owner not in (None, spec.key):  # gym.make would build the new task, get_task the old
        raise ValueError(
            f"task key {spec.key!r} is an alias of the task {owner!r}; choose another key "
            f"(taken: {', '.join([*TASKS, *TASK_ALIASES])})"
        )
    existing = TASKS.get(spec.key)
    if existing is not None and replace and spec.key in BUILTIN_TASKS and existing != spec:
        raise ValueError(
            f"task {spec.key!r} is built into rrls and cannot be replaced (its results are the "
            f"benchmark's); register yours under another key (built-in: "
            f"{', '.join(sorted(BUILTIN_TASKS))})"
        )
    existing = TASKS.get(spec.key)
    if existing is not None and not replace:
        if existing == spec:
            return existing
        raise ValueError(
            f"task {spec.key!r} is already registered with another declaration; "
            "pass replace=True to replace it"
        )
    taken = {t.name: k for k, t in TASKS.items() if k != spec.key}  # class names stay unique
    if spec.name in taken:
        raise ValueError(
            f"class name stem {spec.name!r} is used by task {taken[spec.name]!r}; pass name=..."
        )
    for alias in spec.aliases:
        owner = TASK_ALIASES.get(alias, alias if alias in TASKS else None)
        if owner not in (None, spec.key):
            raise ValueError(f"alias {alias!r} already names task {owner!r}")
    if check:
        validate_task(spec)
    if existing is not None:
        unregister_ids(existing)
    TASKS[spec.key] = spec
    for alias in spec.aliases:
        TASK_ALIASES[alias] = spec.key
    register_ids(spec, replace=existing is not None)
    _changed(spec.key)
    return spec


def _build_spec(
    key: Any,
    env: Any,
    params: Sequence[Parameter],
    sets: Mapping[str, Mapping[str, tuple[float, float]]] | None,
    forces: Sequence[Parameter] | None,
    name: str | None,
    planar: bool,
    env_kwargs: Mapping[str, Any] | None,
    max_episode_steps: int | None,
    aliases: Sequence[str],
) -> TaskSpec:
    if not isinstance(key, str) or not _KEY.match(key):
        raise ValueError(
            f"task key must be lower-case letters and digits starting with a letter "
            f"(it is used in env ids), got {key!r}"
        )
    if isinstance(env, str):
        if env not in registry:
            raise ValueError(f"no Gymnasium env {env!r} is registered")
        env_id, env_class = env, None
        gym_spec = registry[env]
        stem = env.split("/")[-1].split("-v")[0]
        kwargs = dict(gym_spec.kwargs) if env_kwargs is None else dict(env_kwargs)
        steps = max_episode_steps or gym_spec.max_episode_steps or MAX_EPISODE_STEPS
    elif isinstance(env, type):
        from gymnasium.envs.mujoco.mujoco_env import MujocoEnv

        if not issubclass(env, MujocoEnv):
            raise ValueError(f"env must be a Gymnasium MujocoEnv subclass or id, got {env!r}")
        env_id, env_class = None, env
        stem = env.__name__.removesuffix("Env")
        kwargs = dict(env_kwargs or {})
        steps = max_episode_steps or MAX_EPISODE_STEPS
    else:
        raise ValueError(f"env must be a Gymnasium id or a MujocoEnv class, got {env!r}")
    if isinstance(steps, bool) or not isinstance(steps, int) or steps < 1:
        raise ValueError(f"max_episode_steps must be an integer >= 1, got {steps!r}")
    name = name or stem
    if not name.isidentifier():
        raise ValueError(f"class name stem must be an identifier, got {name!r}")
    params = tuple(params)
    bad = [p for p in params if not isinstance(p, Parameter)]
    if bad:
        raise ValueError(f"params must be Parameter rows, got {bad[0]!r}")
    if forces is None:
        parts = {p.name.removesuffix("mass"): p.target for p in params if p.field == "body_mass"}
        forces = force_params(parts, planar)
    forces = tuple(forces)
    if any(f.field != "xfrc_applied" for f in forces):
        raise ValueError("force rows must write 'xfrc_applied'; other fields belong in params")
    if any(p.field == "xfrc_applied" for p in params):
        raise ValueError("forces belong in forces=..., not params=...")
    for table, what in ((params, "params"), (forces, "forces")):
        names = [n for s in table for n in (s.name, *s.aliases)]
        dup = sorted({n for n in names if names.count(n) > 1})
        if dup:
            raise ValueError(f"task {key!r}: duplicate parameter names in {what}: {dup}")
    spec = TaskSpec(
        key=key,
        name=name,
        v5_id=env_id,
        planar=bool(planar),
        params=params,
        forces=forces,
        env_class=env_class,
        env_kwargs=kwargs,
        max_episode_steps=steps,
        aliases=tuple(_normalise(a) for a in aliases),
    )
    clean: dict[str, Bounds] = {}
    families: dict[str, str] = {}
    for set_name, bounds in (sets or {}).items():
        if not isinstance(set_name, str) or not _SET.match(set_name) or set_name == "nominal":
            raise ValueError(
                f"task {key!r}: bad set name {set_name!r} (lower-case letters, digits, '_'; "
                "'nominal' is reserved for the model as shipped)"
            )
        if not bounds:
            raise ValueError(f"task {key!r}: set {set_name!r} names no parameter")
        try:
            families[set_name] = spec.family_of(tuple(bounds))
        except ValueError:
            valid = [n for s in params + forces for n in (s.name,)]
            unknown = [n for n in bounds if n not in valid]
            raise ValueError(
                f"task {key!r}: set {set_name!r} names unknown parameter(s) {unknown} "
                f"(or mixes masses and forces); valid: {', '.join(valid)}"
            ) from None
        table = {s.name: s for s in spec.specs(families[set_name])}
        table.update({a: s for s in spec.specs(families[set_name]) for a in s.aliases})
        box: Bounds = {}
        try:  # the bounds rules of every set (a string "12" is not (1, 2))
            parsed = UncertaintySet.from_bounds(bounds)
        except (TypeError, ValueError) as err:
            raise ValueError(f"task {key!r}: set {set_name!r}: {err}") from None
        for pname, low, high in zip(parsed.names, parsed.low.tolist(), parsed.high.tolist()):
            for v in (low, high):
                problem = table[pname].check(v)
                if problem:
                    raise ValueError(
                        f"task {key!r}: set {set_name!r}: bound out of range: {problem}"
                    )
            box[pname] = (low, high)
        clean[set_name] = box
    if sum(1 for f in families.values() if f == "force") > 1:
        raise ValueError(f"task {key!r}: at most one force set (its id is adversarial-forces)")
    return TaskSpec(**{**spec.__dict__, "sets": clean, "families": families})


def validate_task(spec: TaskSpec) -> None:
    """Compile the task's model once and look up every row by name in it.

    Raises a ``ValueError`` naming the task, the row and the valid bodies / geoms / joints /
    actuators. Used by :func:`register_task` (and by the tests for the built-in tasks).
    """
    from rrls.params import names_of

    env = _build_base(spec)
    try:
        model = env.unwrapped.model
        for family in FAMILIES:
            for row in spec.specs(family):
                try:
                    row.resolve(model)
                except (KeyError, ValueError) as err:
                    message = err.args[0] if err.args else str(err)
                    kind = row.info.target
                    hint = ""
                    if kind in ("body", "geom") and "valid" not in message:
                        hint = f"; valid {kind}s: {', '.join(names_of(model, kind))}"
                    raise ValueError(
                        f"task {spec.key!r}: parameter {row.name!r} ({row.field}): {message}{hint}"
                    ) from None
    finally:
        env.close()


def _build_base(spec: TaskSpec) -> Any:
    import warnings as w

    import mujoco

    cls = spec.base_class()
    previous = mujoco.get_mju_user_warning()
    mujoco.set_mju_user_warning(lambda msg: w.warn(f"MuJoCo: {msg}", stacklevel=2))
    try:
        return cls(**spec.env_kwargs)
    except Exception as err:  # noqa: BLE001 - any failure: one line naming the task
        raise ValueError(
            f"task {spec.key!r}: cannot build {spec.v5_id or cls.__name__} with "
            f"{spec.env_kwargs}: {type(err).__name__}: {err}"
        ) from None
    finally:
        mujoco.set_mju_user_warning(previous)


def unregister_task(key: str) -> None:
    """Forget a registered task and its Gymnasium ids (tests, notebooks re-declaring a task);
    the built-in tasks stay (they could otherwise be replaced through this door)."""
    spec = get_task(key)
    if spec.key in BUILTIN_TASKS:
        raise ValueError(f"task {spec.key!r} is built into rrls and cannot be unregistered")
    unregister_ids(spec)
    del TASKS[spec.key]
    for alias in [a for a, k in TASK_ALIASES.items() if k == spec.key]:
        del TASK_ALIASES[alias]
    _changed(spec.key)


__all__ = [
    "ENTRY_POINT_GROUP",
    "TASKS",
    "TASK_ALIASES",
    "TaskSpec",
    "get_task",
    "load_task_plugins",
    "register_ids",
    "register_task",
    "task_ids",
    "unregister_task",
    "validate_task",
]
