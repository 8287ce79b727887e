"""What every training run is configured by (``TrainConfig``: what, where, how long), the
paper's default set of a task, and the exceptions a run stops with. Torch-free to import (a run
is validated with it): ``rrls benchmark``'s options read its fields' help."""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from typing import Any

from rrls.agents.hparams import check_limits, hp, jsonable, most_threads
from rrls.algorithms import ENTRY_POINTS, built_in
from rrls.envs import training_split
from rrls.physics import SIMULATORS, is_paper, physics_label
from rrls.tasks import benchmark_set
from rrls.twin.catalog import check_twin

__all__ = ["Diverged", "Interrupted", "TrainConfig", "benchmark_set", "training_split"]


@dataclass
class TrainConfig:
    """One training run: what, where, how long. The algorithm's hyper-parameters are its own
    dataclass (``rrls.agents.algos.<algo>.Config``, the paper's values); ``hyper`` overrides fields
    of it (``{"learning_rate": 1e-3}``, what a benchmark's template holds: it needs no torch) or
    is that ``Config`` itself (``td3.Config(learning_rate=1e-3)``). Either way the run resolves
    it once (``rrls.agents.lookup.resolve_run``) and ``run.json`` stores every resolved field.
    ``rrls train`` offers every field of both as an option."""

    algo: str = hp(
        "td3",
        f"the algorithm: {', '.join(built_in())}, an installed plug-in (entry point group "
        f"{ENTRY_POINTS!r}) or package.module:Learner",
    )
    task: str = hp("hopper", "the task")
    uncertainty: str | None = hp(
        None,
        "the uncertainty set trained on (and evaluated over): any set the task declares (the "
        "paper's tasks: 1d, 2d, 3d, rarl (forces))",
        default_text="the paper's benchmark set, 3d (2d where the task has no 3d set)",
    )
    split: str | None = hp(
        None,
        "train on the inner part of the set only: extrapolation[:F] (the centred box, a "
        "fraction F of each axis, default 0.5; rrls's own extrapolation split): every algorithm "
        "that trains on the set (DR, M2TD3, RARL, SAC-DR) sees only that box, and the "
        "evaluations still cover the whole set, the rest being out of distribution",
    )
    steps: int = hp(5_000_000, "training env steps of a run: 30000, 1e4, 100k")
    seed: int = hp(0, "seed of every random draw: each purpose a child of SeedSequence(seed)")
    out: str | None = hp(None, "run directory (default runs/<algo>-<task>-<set>-seed<S>)")
    device: str = hp("cpu", "torch device: cpu, cuda or cuda:N")
    threads: int | None = hp(
        None,
        "torch threads (default: the cores other processes leave idle, re-checked every few "
        "seconds, so runs sharing a machine never oversubscribe it; at most 4 per core)",
        most=most_threads,
    )
    cuda_graphs: bool = hp(
        True,
        "on cuda: replay each update from a captured CUDA graph (one launch instead of "
        "hundreds of small kernels; --no-cuda-graphs runs them eagerly)",
    )
    compile: bool | None = hp(
        None,
        "torch.compile each update whole (losses, backward and Adam: inductor's C++ kernels on "
        "a CPU, Triton ones replayed from CUDA graphs on cuda). Default: on cuda when the run "
        "has 20 000 updates or more left, enough to pay for compiling; off for shorter runs and "
        "on a CPU (measured: no faster there, the GEMMs dominate); --no-compile: eager. "
        "Compiling costs ~35 s the first time on a machine and ~4 s after: the kernels are "
        "cached in $TORCHINDUCTOR_CACHE_DIR (default ~/.cache/rrls/inductor), shared by every "
        "later run and resume",
    )
    env_workers: int | None = hp(
        None,
        "processes stepping the envs of runs trained together (0: this process; default: "
        "0 on a CPU, on a GPU one per 4 envs of a group of 16 or more)",
        most=1024,
    )
    eval_every: int = hp(50_000, "evaluate every N steps (0: never)")
    eval_episodes: int = hp(5, "episodes per point of the periodic evaluation", most=10_000)
    eval_mesh: int = hp(
        0,
        "periodic evaluation also over a mesh of N points per dimension (0: nominal only)",
        most=1_000,
    )
    checkpoint_every: int = hp(
        50_000, "checkpoint every N steps (an episode in progress is replayed on resume)"
    )
    max_episode_steps: int | None = hp(
        None, "time limit: episodes are truncated here (default: the task's, e.g. 1000, Reacher 50)"
    )
    physics: str = hp(
        "v5",
        "v5 (Gymnasium v5 envs, rrls's parameter semantics) or paper (the paper's Gymnasium v5 "
        "envs, the original code's parameter writes; the paper's six tasks)",
        choices=["v5", "paper"],
    )
    simulator: str = hp(
        "mujoco",
        "what steps the training envs: mujoco (CPU MuJoCo, the reference) or warp (the task's "
        "MuJoCo Warp twin on --device, run k on world k: rrls.twin; needs the warp extra). "
        "Evaluations stay on CPU MuJoCo either way",
        choices=list(SIMULATORS),
    )
    track: bool = hp(False, "also log to Weights & Biases (needs wandb installed)")
    wandb_project: str = hp("rrls", "the W&B project of --track")
    progress: bool | None = None  # progress bar (None: when stderr is a terminal)
    overwrite: bool = hp(False, "replace a finished run in --out")
    #: overrides of the algorithm's ``Config`` fields, or that ``Config`` itself
    hyper: dict[str, Any] | Any = field(default_factory=dict)

    def __post_init__(self) -> None:
        from rrls.agents.lookup import algorithm  # torch: the fields are read without it
        from rrls.tasks import TASKS, get_task

        algorithm(self.algo)  # ValueError naming the valid ones
        task = get_task(self.task)  # ValueError listing the tasks
        self.task = task.key
        if self.uncertainty is None:
            self.uncertainty = benchmark_set(task.key)
        if self.uncertainty not in task.sets:
            raise ValueError(
                f"task {task.key!r} has no uncertainty set {self.uncertainty!r}; "
                f"valid: {', '.join(task.sets)}"
            )
        if self.split is not None:
            self.split = training_split(task.key, self.uncertainty, self.split)
        if self.max_episode_steps is None:
            self.max_episode_steps = task.max_episode_steps
        self.physics = physics_label(self.physics)  # ValueError naming the valid ones
        if is_paper(self.physics) and task.paper_id is None:
            raise ValueError(
                f"task {task.key!r} has no paper physics; valid with --physics paper: "
                + ", ".join(k for k, t in TASKS.items() if t.paper_id is not None)
            )
        if self.simulator not in SIMULATORS:
            raise ValueError(f"simulator {self.simulator!r}; valid: {', '.join(SIMULATORS)}")
        if self.simulator == "warp":
            check_twin(self.algo, task.key, self.physics)
        if self.out is None:
            paper = "-paper" if is_paper(self.physics) else ""
            split = "-" + self.split.replace(":", "") if self.split else ""
            self.out = (
                f"runs/{self.algo}-{task.key}-{self.uncertainty}{split}{paper}-seed{self.seed}"
            )
        checks = {
            "steps": self.steps >= 1,
            "seed": self.seed >= 0,
            "eval_every": self.eval_every >= 0,
            "eval_episodes": self.eval_episodes >= 1,
            "eval_mesh": self.eval_mesh >= 0,
            "checkpoint_every": self.checkpoint_every >= 1,
            "max_episode_steps": self.max_episode_steps >= 1,
            "threads": self.threads is None or self.threads >= 1,
            "env_workers": self.env_workers is None or self.env_workers >= 0,
        }
        for name, ok in checks.items():
            if not ok:
                raise ValueError(f"{name} out of range: {getattr(self, name)}")
        check_limits(self)
        import torch

        try:
            device = torch.device(self.device)
        except RuntimeError as err:
            raise ValueError(f"device {self.device!r} is not a torch device: {err}") from None
        if device.type == "cuda" and not torch.cuda.is_available():
            raise ValueError(f"device {self.device!r}: no CUDA device is available")
        if device.type not in ("cpu", "cuda"):
            raise ValueError(f"device {self.device!r}: rrls trains on cpu or cuda")

    def identity(self, hyper: Any) -> dict[str, Any]:
        """What must match for ``--resume`` (``steps`` may grow, logging options may change)."""
        return {
            "algo": self.algo,
            "task": self.task,
            "uncertainty": self.uncertainty,
            **({"split": self.split} if self.split else {}),  # older runs: no key
            "seed": self.seed,
            "max_episode_steps": self.max_episode_steps,
            "physics": self.physics,
            **({"simulator": self.simulator} if self.simulator != "mujoco" else {}),
            "hyper": jsonable(asdict(hyper)),
        }

    def training_set(self) -> Any:
        """What ``make_env`` gets as its ``uncertainty``: the set's name, or under ``split`` the
        training part as an ``UncertaintySet`` (the inner box; ``rrls.envs.resolve`` and
        ``task_env`` take either)."""
        if not self.split:
            return self.uncertainty
        from rrls.envs import get_uncertainty_set
        from rrls.uncertainty import Split, UncertaintySet

        box = get_uncertainty_set(self.task, self.uncertainty)
        region = Split.parse(box, self.split).region
        label = f"{box.label} {self.split} (training part)"
        return UncertaintySet(region.names, region.low, region.high, None, label, box.family)


class Interrupted(Exception):
    """The run stopped right after a checkpoint, as if killed (``RRLS_STOP_AT``); ``--resume``
    continues it."""


class Diverged(ValueError):
    """A learner produced a NaN/inf action or policy: training stops before writing it (the
    CLI prints it on one line); the last checkpoint stays, so nothing trained so far is lost."""
