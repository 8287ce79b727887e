"""The env classes of the built-in tasks, one ``class`` statement each.

``Robust<Task>`` exposes the task's physical parameters, ``Force<Task>`` its external forces;
for the paper's six tasks ``PaperRobust<Task>``/``PaperForce<Task>`` are the same on the paper's
physics (the v5 env the original code built and its writes, :mod:`rrls.envs.paper`), what
``Robust<Task>(paper=True)`` builds. Each is Gymnasium's v5 class with
:class:`~rrls.envs.base.ModifiedParamsMixin` in front; ``@task_env`` fills in what the task table
declares (the parameter list, the docstring's parameters and example), so the table stays the one
declaration. A task registered later (``rrls.register_task``) gets its classes from the same
:func:`class_attributes` (``rrls.envs.env_classes``).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from gymnasium.envs.mujoco.ant_v5 import AntEnv
from gymnasium.envs.mujoco.half_cheetah_v5 import HalfCheetahEnv
from gymnasium.envs.mujoco.hopper_v5 import HopperEnv
from gymnasium.envs.mujoco.humanoid_v5 import HumanoidEnv
from gymnasium.envs.mujoco.humanoidstandup_v5 import HumanoidStandupEnv
from gymnasium.envs.mujoco.inverted_double_pendulum_v5 import InvertedDoublePendulumEnv
from gymnasium.envs.mujoco.inverted_pendulum_v5 import InvertedPendulumEnv
from gymnasium.envs.mujoco.pusher_v5 import PusherEnv
from gymnasium.envs.mujoco.reacher_v5 import ReacherEnv
from gymnasium.envs.mujoco.swimmer_v5 import SwimmerEnv
from gymnasium.envs.mujoco.walker2d_v5 import Walker2dEnv

from rrls.envs.base import ModifiedParamsMixin
from rrls.envs.paper import paper_specs
from rrls.tasks import TASKS, TaskSpec

#: the tasks whose class docstrings carry a doctest (the paper's six: one example per kind)
DOCTESTED = ("ant", "halfcheetah", "hopper", "humanoidstandup", "invertedpendulum", "walker")


def class_name(task: TaskSpec, kind: str, paper: bool = False) -> str:
    """``Robust<Task>``, ``Force<Task>``, ``PaperRobust<Task>``, ``PaperForce<Task>``."""
    return f"{'Paper' if paper else ''}{kind.capitalize()}{task.name}"


def class_attributes(
    task: TaskSpec, kind: str, paper: bool = False, summary: str | None = None
) -> dict[str, Any]:
    """What a task's env class of family ``kind`` holds beyond its bases: the declaration, the
    parameters it exposes (``paper``: written as the original code writes them) and a docstring
    listing them (``summary``: its first line)."""
    specs = paper_specs(task, kind) if paper else task.params if kind == "robust" else task.forces
    name = class_name(task, kind, paper)
    what = "physical parameters" if kind == "robust" else "external forces (world frame, N)"
    base = task.base_class(paper)
    built_on = task.paper_id if paper else task.v5_id or base.__name__
    masses = [s.name for s in specs if s.field in ("body_mass", "xfrc_applied")]
    first = masses[-1] if masses else specs[-1].name if specs else None
    example = (
        f"""
    >>> from rrls.envs import {name}
    >>> env = {name}({first}=1.5)
    >>> obs, info = env.reset(seed=0)
    >>> info["{first}"]
    1.5
    >>> env.set_params({first}=0.5)
    >>> env.get_params()["{first}"]
    0.5
    """
        if task.key in DOCTESTED and first and not paper
        else ""
    )
    summary = summary or f"Gymnasium's ``{built_on}`` whose {what} can be read and changed."
    doc = f"""{summary}

    Parameters: {", ".join(s.name for s in specs)}.
    {example}"""
    return {"task": task, "param_specs": specs, "paper": paper, "__doc__": doc}


#: (task key, family, paper) -> its class statement below, filled in by ``task_env``
BUILT_IN: dict[tuple[str, str, bool], type] = {}


def task_env(
    key: str, kind: str = "robust", paper: bool = False, twin: type | None = None
) -> Callable[[type], type]:
    """Fill a built-in task's class statement from the task table; ``twin``: its class on the
    paper's physics (what ``paper=True`` builds)."""

    def fill(cls: type) -> type:
        summary = (cls.__doc__ or "").strip() or None
        for attr, value in class_attributes(TASKS[key], kind, paper, summary).items():
            setattr(cls, attr, value)
        if twin is not None:
            cls.paper_twin = staticmethod(lambda: twin)
        BUILT_IN[(key, kind, paper)] = cls
        return cls

    return fill


@task_env("ant", "robust", paper=True)
class PaperRobustAnt(ModifiedParamsMixin, AntEnv):
    """The paper's physics: the Ant-v5 env the original code built, and its writes."""


@task_env("ant", "force", paper=True)
class PaperForceAnt(ModifiedParamsMixin, AntEnv):
    """The paper's physics: the Ant-v5 env the original code built, and its writes."""


@task_env("ant", "robust", twin=PaperRobustAnt)
class RobustAnt(ModifiedParamsMixin, AntEnv):
    """Gymnasium's ``Ant-v5`` whose physical parameters can be read and changed."""


@task_env("ant", "force", twin=PaperForceAnt)
class ForceAnt(ModifiedParamsMixin, AntEnv):
    """Gymnasium's ``Ant-v5`` whose external forces (world frame, N) can be changed."""


@task_env("halfcheetah", "robust", paper=True)
class PaperRobustHalfCheetah(ModifiedParamsMixin, HalfCheetahEnv):
    """The paper's physics: the HalfCheetah-v5 env the original code built, and its writes."""


@task_env("halfcheetah", "force", paper=True)
class PaperForceHalfCheetah(ModifiedParamsMixin, HalfCheetahEnv):
    """The paper's physics: the HalfCheetah-v5 env the original code built, and its writes."""


@task_env("halfcheetah", "robust", twin=PaperRobustHalfCheetah)
class RobustHalfCheetah(ModifiedParamsMixin, HalfCheetahEnv):
    """Gymnasium's ``HalfCheetah-v5`` whose physical parameters can be read and changed."""


@task_env("halfcheetah", "force", twin=PaperForceHalfCheetah)
class ForceHalfCheetah(ModifiedParamsMixin, HalfCheetahEnv):
    """Gymnasium's ``HalfCheetah-v5`` whose external forces (world frame, N) can be changed."""


@task_env("hopper", "robust", paper=True)
class PaperRobustHopper(ModifiedParamsMixin, HopperEnv):
    """The paper's physics: the Hopper-v5 env the original code built, and its writes."""


@task_env("hopper", "force", paper=True)
class PaperForceHopper(ModifiedParamsMixin, HopperEnv):
    """The paper's physics: the Hopper-v5 env the original code built, and its writes."""


@task_env("hopper", "robust", twin=PaperRobustHopper)
class RobustHopper(ModifiedParamsMixin, HopperEnv):
    """Gymnasium's ``Hopper-v5`` whose physical parameters can be read and changed."""


@task_env("hopper", "force", twin=PaperForceHopper)
class ForceHopper(ModifiedParamsMixin, HopperEnv):
    """Gymnasium's ``Hopper-v5`` whose external forces (world frame, N) can be changed."""


@task_env("humanoidstandup", "robust", paper=True)
class PaperRobustHumanoidStandUp(ModifiedParamsMixin, HumanoidStandupEnv):
    """The paper's physics: the HumanoidStandup-v5 env the original code built, and its writes."""


@task_env("humanoidstandup", "force", paper=True)
class PaperForceHumanoidStandUp(ModifiedParamsMixin, HumanoidStandupEnv):
    """The paper's physics: the HumanoidStandup-v5 env the original code built, and its writes."""


@task_env("humanoidstandup", "robust", twin=PaperRobustHumanoidStandUp)
class RobustHumanoidStandUp(ModifiedParamsMixin, HumanoidStandupEnv):
    """Gymnasium's ``HumanoidStandup-v5`` whose physical parameters can be read and changed."""


@task_env("humanoidstandup", "force", twin=PaperForceHumanoidStandUp)
class ForceHumanoidStandUp(ModifiedParamsMixin, HumanoidStandupEnv):
    """Gymnasium's ``HumanoidStandup-v5`` whose external forces (world frame, N) can be changed."""


@task_env("invertedpendulum", "robust", paper=True)
class PaperRobustInvertedPendulum(ModifiedParamsMixin, InvertedPendulumEnv):
    """The paper's physics: the InvertedPendulum-v5 env the original code built, and its writes."""


@task_env("invertedpendulum", "force", paper=True)
class PaperForceInvertedPendulum(ModifiedParamsMixin, InvertedPendulumEnv):
    """The paper's physics: the InvertedPendulum-v5 env the original code built, and its writes."""


@task_env("invertedpendulum", "robust", twin=PaperRobustInvertedPendulum)
class RobustInvertedPendulum(ModifiedParamsMixin, InvertedPendulumEnv):
    """Gymnasium's ``InvertedPendulum-v5`` whose physical parameters can be read and changed."""


@task_env("invertedpendulum", "force", twin=PaperForceInvertedPendulum)
class ForceInvertedPendulum(ModifiedParamsMixin, InvertedPendulumEnv):
    """Gymnasium's ``InvertedPendulum-v5`` whose external forces (world frame, N) can be changed."""


@task_env("walker", "robust", paper=True)
class PaperRobustWalker2d(ModifiedParamsMixin, Walker2dEnv):
    """The paper's physics: the Walker2d-v5 env the original code built, and its writes."""


@task_env("walker", "force", paper=True)
class PaperForceWalker2d(ModifiedParamsMixin, Walker2dEnv):
    """The paper's physics: the Walker2d-v5 env the original code built, and its writes."""


@task_env("walker", "robust", twin=PaperRobustWalker2d)
class RobustWalker2d(ModifiedParamsMixin, Walker2dEnv):
    """Gymnasium's ``Walker2d-v5`` whose physical parameters can be read and changed."""


@task_env("walker", "force", twin=PaperForceWalker2d)
class ForceWalker2d(ModifiedParamsMixin, Walker2dEnv):
    """Gymnasium's ``Walker2d-v5`` whose external forces (world frame, N) can be changed."""


@task_env("humanoid", "robust")
class RobustHumanoid(ModifiedParamsMixin, HumanoidEnv):
    """Gymnasium's ``Humanoid-v5`` whose physical parameters can be read and changed."""


@task_env("humanoid", "force")
class ForceHumanoid(ModifiedParamsMixin, HumanoidEnv):
    """Gymnasium's ``Humanoid-v5`` whose external forces (world frame, N) can be changed."""


@task_env("swimmer", "robust")
class RobustSwimmer(ModifiedParamsMixin, SwimmerEnv):
    """Gymnasium's ``Swimmer-v5`` whose physical parameters can be read and changed."""


@task_env("swimmer", "force")
class ForceSwimmer(ModifiedParamsMixin, SwimmerEnv):
    """Gymnasium's ``Swimmer-v5`` whose external forces (world frame, N) can be changed."""


@task_env("inverteddoublependulum", "robust")
class RobustInvertedDoublePendulum(ModifiedParamsMixin, InvertedDoublePendulumEnv):
    """Gymnasium's ``InvertedDoublePendulum-v5`` whose physical parameters can change."""


@task_env("inverteddoublependulum", "force")
class ForceInvertedDoublePendulum(ModifiedParamsMixin, InvertedDoublePendulumEnv):
    """Gymnasium's ``InvertedDoublePendulum-v5`` with external forces (world frame, N)."""


@task_env("reacher", "robust")
class RobustReacher(ModifiedParamsMixin, ReacherEnv):
    """Gymnasium's ``Reacher-v5`` whose physical parameters can be read and changed."""


@task_env("reacher", "force")
class ForceReacher(ModifiedParamsMixin, ReacherEnv):
    """Gymnasium's ``Reacher-v5`` whose external forces (world frame, N) can be changed."""


@task_env("pusher", "robust")
class RobustPusher(ModifiedParamsMixin, PusherEnv):
    """Gymnasium's ``Pusher-v5`` whose physical parameters can be read and changed."""


@task_env("pusher", "force")
class ForcePusher(ModifiedParamsMixin, PusherEnv):
    """Gymnasium's ``Pusher-v5`` whose external forces (world frame, N) can be changed."""


__all__ = [
    "BUILT_IN",
    "DOCTESTED",
    "ForceAnt",
    "ForceHalfCheetah",
    "ForceHopper",
    "ForceHumanoid",
    "ForceHumanoidStandUp",
    "ForceInvertedDoublePendulum",
    "ForceInvertedPendulum",
    "ForcePusher",
    "ForceReacher",
    "ForceSwimmer",
    "ForceWalker2d",
    "PaperForceAnt",
    "PaperForceHalfCheetah",
    "PaperForceHopper",
    "PaperForceHumanoidStandUp",
    "PaperForceInvertedPendulum",
    "PaperForceWalker2d",
    "PaperRobustAnt",
    "PaperRobustHalfCheetah",
    "PaperRobustHopper",
    "PaperRobustHumanoidStandUp",
    "PaperRobustInvertedPendulum",
    "PaperRobustWalker2d",
    "RobustAnt",
    "RobustHalfCheetah",
    "RobustHopper",
    "RobustHumanoid",
    "RobustHumanoidStandUp",
    "RobustInvertedDoublePendulum",
    "RobustInvertedPendulum",
    "RobustPusher",
    "RobustReacher",
    "RobustSwimmer",
    "RobustWalker2d",
    "class_attributes",
    "class_name",
    "task_env",
]
