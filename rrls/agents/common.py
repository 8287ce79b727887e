"""What every training run shares: configuration, the run directory, checkpoints, logs, evaluation.

Checkpoints are taken at episode boundaries — just before the environment is reset — so a run
restores its networks, optimisers, replay buffer, every random generator and its counters, then
redoes that reset from the restored generator: the resumed run continues exactly as the
uninterrupted one would (tested bit for bit). Files are written atomically and loaded with
``torch.load(weights_only=True)``; generator states travel as JSON text.
"""

from __future__ import annotations

import io
import json
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import torch

from rrls._io import atomic_write_bytes, atomic_write_json
from rrls.agents.core import TD3Config, hp

ALGOS = ("td3", "dr", "rarl", "nrmdp", "m2td3")


def benchmark_set(task: str) -> str:
    """The paper's benchmark set (§5: every baseline trains on the 3D set; InvertedPendulum,
    which has no 3D set, on its 2D set)."""
    from rrls.tasks import get_task

    return "2d" if "3d" not in get_task(task).sets else "3d"


@dataclass
class TrainConfig:
    """One training run: what, where, how long. The algorithm's hyper-parameters are its own
    dataclass (``rrls.agents.<algo>.Config``, the paper's values); ``hyper`` overrides fields of
    it (``{"learning_rate": 1e-3}``). ``rrls train`` offers every field of both as an option."""

    algo: str = hp("td3", "the baseline", choices=ALGOS)
    task: str = hp("hopper", "the task")
    uncertainty: str | None = hp(
        None,
        "the uncertainty set trained on (and evaluated over): 1d, 2d, 3d or rarl (forces); "
        "default: the paper's benchmark set, 3d (2d for invertedpendulum)",
    )
    steps: int = hp(5_000_000, "env steps")
    seed: int = hp(0, "seed of every random draw (networks, replay, env, noise)")
    out: str | None = hp(None, "run directory (default runs/<algo>-<task>-<set>-seed<S>)")
    device: str = hp("cpu", "torch device: cpu, cuda or cuda:N")
    threads: int | None = hp(
        None,
        "torch threads (default: the cores other processes leave idle, re-checked every few "
        "seconds, so runs sharing a machine never oversubscribe it)",
    )
    cuda_graphs: bool = hp(
        True,
        "on cuda: replay each update from a captured CUDA graph (one launch instead of "
        "hundreds of small kernels; --no-cuda-graphs runs them eagerly)",
    )
    env_workers: int | None = hp(
        None,
        "processes stepping the envs of runs trained together (0: this process; default: "
        "0 on a CPU, on a GPU one per 8 envs of a group of 16 or more)",
    )
    eval_every: int = hp(50_000, "evaluate every N steps (0: never)")
    eval_episodes: int = hp(5, "episodes per point of the periodic evaluation")
    eval_mesh: int = hp(
        0, "periodic evaluation also over a mesh of N points per dimension (0: nominal only)"
    )
    checkpoint_every: int = hp(
        50_000, "checkpoint every N steps (an episode in progress is replayed on resume)"
    )
    max_episode_steps: int = hp(1000, "time limit: episodes are truncated here")
    progress: bool | None = None  # progress bar (None: when stderr is a terminal)
    overwrite: bool = hp(False, "replace a finished run in --out")
    stop_at: int | None = None  # testing aid: stop (as if killed) at the first checkpoint >= this
    hyper: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        from rrls.tasks import get_task

        if self.algo not in ALGOS:
            raise ValueError(f"unknown algorithm {self.algo!r}; valid: {', '.join(ALGOS)}")
        task = get_task(self.task)  # ValueError listing the tasks
        self.task = task.key
        if self.uncertainty is None:
            self.uncertainty = benchmark_set(task.key)
        if self.uncertainty not in task.sets:
            raise ValueError(
                f"task {task.key!r} has no uncertainty set {self.uncertainty!r}; "
                f"valid: {', '.join(task.sets)}"
            )
        if self.out is None:
            self.out = f"runs/{self.algo}-{task.key}-{self.uncertainty}-seed{self.seed}"
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
        try:
            device = torch.device(self.device)
        except RuntimeError as err:
            raise ValueError(f"device {self.device!r} is not a torch device: {err}") from None
        if device.type == "cuda" and not torch.cuda.is_available():
            raise ValueError(f"device {self.device!r}: no CUDA device is available")
        if device.type not in ("cpu", "cuda"):
            raise ValueError(f"device {self.device!r}: rrls trains on cpu or cuda")

    def identity(self, hyper: TD3Config) -> dict[str, Any]:
        """What must match for ``--resume`` (``steps`` may grow, logging options may change)."""
        return {
            "algo": self.algo,
            "task": self.task,
            "uncertainty": self.uncertainty,
            "seed": self.seed,
            "max_episode_steps": self.max_episode_steps,
            "hyper": _jsonable(asdict(hyper)),
        }


class Interrupted(Exception):
    """Raised by ``stop_at`` (a test aid): the run stops right after a checkpoint."""


def versions() -> dict[str, str]:
    """The evaluation's version record plus torch (saved with every policy)."""
    from rrls.evaluation.evaluate import _versions

    return {**_versions(), "torch": torch.__version__}


def rng_state(gen: np.random.Generator) -> str:
    return json.dumps(gen.bit_generator.state)


def set_rng_state(gen: np.random.Generator, state: str) -> None:
    gen.bit_generator.state = json.loads(state)


def task_env(task: str, uncertainty: str = "nominal") -> tuple[Any, Any]:
    """A bare env of ``task`` (no time limit: the loop truncates) of the family ``uncertainty``
    needs (``rrls.envs.resolve``, the one place that decides), and the set's box (``None`` for
    the nominal task)."""
    from rrls.envs import resolve

    resolved = resolve(task, uncertainty)
    return resolved.make_env(), (None if resolved.is_nominal else resolved.box)


class Run:
    """The run directory: TensorBoard logs, progress bar, checkpoints, evaluation, final policy."""

    def __init__(
        self,
        config: TrainConfig,
        resume: bool = False,
        hyper: TD3Config | None = None,
    ) -> None:
        from rrls.tasks import get_task

        self.config = config
        self.hyper = hyper if hyper is not None else TD3Config()
        self.task = get_task(config.task).key
        self.uncertainty = config.uncertainty
        self.dir = Path(config.out)
        self.checkpoint_path = self.dir / "checkpoint.pt"
        self.step = 0
        self.episodes = 0
        self.finished = False
        self._bar: Any = None
        self._writer: Any = None
        self._scalars: Any = None
        done = _finished_steps(self.dir)
        if config.overwrite:
            _remove_run_files(self.dir)
        elif done is not None:
            if not resume:
                raise FileExistsError(
                    f"{self.dir} holds a finished run ({done} steps): pass --overwrite to "
                    "replace it, --resume with more --steps to extend it, or another --out"
                )
            if config.steps <= done:
                if self.checkpoint_path.exists():
                    self._check_identity(self._read_checkpoint())
                if config.steps < done:
                    raise ValueError(
                        f"cannot resume {self.dir}: it has already trained {done} steps, "
                        f"more than --steps {config.steps}"
                    )
                self.finished, self.step = True, done
                return
        elif self.checkpoint_path.exists() and not resume:
            raise FileExistsError(
                f"{self.dir} already holds a run: pass --resume to continue it, --overwrite to "
                "replace it, or another --out"
            )
        self.dir.mkdir(parents=True, exist_ok=True)
        _remove_temporary_files(self.dir)  # left by a write killed half-way
        self.resumed = resume and self.checkpoint_path.exists()
        if not self.resumed:  # a fresh start: curves and logs of a run killed before its
            _remove_run_files(self.dir)  # first checkpoint would otherwise be appended to
        self.scalars_path = self.dir / "scalars.csv"
        self._scalars: Any = None
        self._last_checkpoint = 0
        self._last_eval = 0
        self._writer: Any = None
        self._bar: Any = None
        self._t0 = time.perf_counter()
        self._t0_step = 0

    # -- checkpoints ------------------------------------------------------------------------
    def _read_checkpoint(self) -> dict[str, Any]:
        """The checkpoint, or a one-line error naming the file when it cannot be used."""
        path = self.checkpoint_path
        try:
            state = torch.load(path, weights_only=True, map_location="cpu")
        except Exception as err:  # empty, truncated, not a checkpoint: all say the same
            raise ValueError(
                f"cannot resume from {path}: the file is not a readable checkpoint "
                f"({type(err).__name__}); delete it (or pass --overwrite) to start again"
            ) from None
        if not isinstance(state, dict) or "learner" not in state or "config" not in state:
            raise ValueError(
                f"cannot resume from {path}: it was written by another version of rrls "
                "(another layout); pass --overwrite to start again"
            )
        return state

    def _check_identity(self, state: dict[str, Any]) -> None:
        saved = json.loads(state["config"])
        current = self.config.identity(self.hyper)
        diff = [k for k in current if k != "hyper" and saved.get(k) != current[k]]
        diff += [
            k for k in current["hyper"] if saved.get("hyper", {}).get(k) != current["hyper"][k]
        ]
        if diff:
            raise ValueError(
                f"cannot resume {self.dir}: it was trained with other {', '.join(sorted(diff))}"
            )

    def load(self) -> dict[str, Any] | None:
        """The saved state when resuming (checked against this config), else ``None``."""
        if not self.resumed:
            return None
        state = self._read_checkpoint()
        self._check_identity(state)
        if int(state["step"]) > self.config.steps:
            raise ValueError(
                f"cannot resume from {self.checkpoint_path}: it is at step {int(state['step'])}, "
                f"beyond --steps {self.config.steps}"
            )
        self.step, self.episodes = int(state["step"]), int(state["episodes"])
        self._last_checkpoint = self.step
        self._last_eval = int(state["last_eval"])
        _truncate_scalars(self.scalars_path, self.step)
        return state

    def checkpoint_due(self) -> bool:
        return self.step - self._last_checkpoint >= self.config.checkpoint_every

    def save(self, state: dict[str, Any]) -> None:
        """Write the checkpoint atomically (call at an episode boundary, before the reset)."""
        state = {
            **state,
            "step": self.step,
            "episodes": self.episodes,
            "last_eval": self._last_eval,
            "config": json.dumps(self.config.identity(self.hyper)),
        }
        buf = io.BytesIO()
        torch.save(state, buf)
        if self._scalars is not None:  # the curves reach at least as far as the checkpoint
            self._scalars.flush()
        atomic_write_bytes(self.checkpoint_path, buf.getvalue())
        self._last_checkpoint = self.step

    def check_stop(self) -> None:
        """``stop_at`` (a test aid): stop as if killed, right after a checkpoint."""
        stop = self.config.stop_at
        if stop is not None and self.step >= stop:
            raise Interrupted(f"stopped at step {self.step} (stop_at={stop})")

    # -- logs -------------------------------------------------------------------------------
    @property
    def writer(self) -> Any:
        if self._writer is None:
            try:
                from torch.utils.tensorboard import SummaryWriter
            except ImportError:  # tensorboard is part of the `train` extra
                self._writer = _NullWriter()
            else:
                self._writer = SummaryWriter(str(self.dir / "tb"), purge_step=self.step or None)
        return self._writer

    def log(self, values: dict[str, float], step: int | None = None) -> None:
        step = self.step if step is None else step
        for key, value in values.items():
            self.writer.add_scalar(key, float(value), step)

    def record(self, values: dict[str, float]) -> None:
        """Log ``values`` and append them to ``scalars.csv`` (``step,metric,value``): the
        training curves as a plain table, for reports that must not parse TensorBoard files."""
        self.log(values)
        if self._scalars is None:
            new = not self.scalars_path.exists()
            self._scalars = open(self.scalars_path, "a", encoding="utf-8")  # noqa: SIM115
            if new:
                self._scalars.write("step,metric,value\n")
        self._scalars.writelines(
            f"{self.step},{key},{float(value)!r}\n" for key, value in values.items()
        )

    def progress(self, group: int = 1) -> Any:
        import sys

        from tqdm.auto import tqdm

        disable = (
            not sys.stderr.isatty() if self.config.progress is None else not self.config.progress
        )
        self._bar = tqdm(
            total=self.config.steps * group,
            initial=self.step * group,
            unit="step",
            desc=f"{self.config.algo} {self.task}" + (f" ({group} runs)" if group > 1 else ""),
            disable=disable,
            smoothing=0.05,
        )
        self._t0, self._t0_step = time.perf_counter(), self.step
        return self._bar

    def episode_end(self, episode_return: float, length: int, **extra: float) -> None:
        self.episodes += 1
        elapsed = time.perf_counter() - self._t0
        sps = (self.step - self._t0_step) / elapsed if elapsed > 0 else 0.0
        self.record(
            {
                "charts/episode_return": episode_return,
                "charts/episode_length": length,
                "charts/steps_per_second": sps,
                **extra,
            }
        )
        if self._bar is not None:
            self._bar.set_postfix(ret=f"{episode_return:.1f}", refresh=False)

    # -- evaluation -------------------------------------------------------------------------
    def eval_due(self) -> bool:
        every = self.config.eval_every
        return every > 0 and self.step - self._last_eval >= every

    def evaluate(self, policy: Any) -> dict[str, float]:
        """Nominal return (and the coarse-mesh worst/average case) of ``policy`` (the run's
        ``MLPPolicy``) through the evaluation engine."""
        from rrls.evaluation import evaluate

        self._last_eval = self.step
        cfg = self.config
        nominal = evaluate(
            policy,
            self.task,
            "nominal",
            episodes=cfg.eval_episodes,
            seed=10_000,
            workers=1,
            progress=False,
        )
        scores = {"eval/nominal_return": nominal.average_case}
        if cfg.eval_mesh > 0:
            mesh = evaluate(
                policy,
                self.task,
                self.eval_set(),
                nb_mesh_dim=cfg.eval_mesh,
                episodes=1,
                seed=10_000,
                workers=1,
                progress=False,
            )
            scores.update(
                {"eval/worst_case": mesh.worst_case, "eval/average_case": mesh.average_case}
            )
        self.record(scores)
        return scores

    def eval_set(self) -> str:
        """The set of the periodic mesh evaluation: the run's, or the benchmark's for forces."""
        from rrls.envs import resolve

        if resolve(self.task, self.uncertainty).family == "force":
            return benchmark_set(self.task)
        return self.uncertainty

    def metadata(self, env: Any, learner: Any, k: int = 0) -> dict[str, Any]:
        """What the saved policies record (``rrls evaluate RUN_DIR`` reads task and set)."""
        return {
            "algorithm": self.config.algo,
            "task": self.task,
            "uncertainty": self.uncertainty,
            "obs_dim": env.observation_space.shape[0],
            "act_dim": learner.actor.act_dim,
            "hidden": list(self.hyper.hidden),
            "seed": self.config.seed,
            "run_dir": str(self.dir),
            "versions": versions(),
            **(learner.game or {}),
        }

    # -- the end ----------------------------------------------------------------------------
    def finish(
        self,
        policy: Any,
        actor_state: dict[str, torch.Tensor],
        metadata: dict[str, Any],
        summary: dict[str, Any],
        adversary: Any = None,
    ) -> Path:
        """Save the final policy (``policy.npz``, an ``MLPPolicy``; ``actor.pt``: the run's actor
        tensors only) and ``run.json``; for two-player runs also the final adversary
        (``adversary.npz``, same safe format, its metadata saying which game and set it plays),
        for the dynamic evaluation (Table 6)."""
        if adversary is not None:
            adversary.save(self.dir / "adversary.npz")
        policy.save(self.dir / "policy.npz")
        buf = io.BytesIO()
        torch.save(actor_state, buf)
        atomic_write_bytes(self.dir / "actor.pt", buf.getvalue())
        atomic_write_json(
            self.dir / "run.json",
            {
                **metadata,
                "config": _jsonable(asdict(self.config)),
                "hyperparameters": _jsonable(asdict(self.hyper)),
                **summary,
            },
        )
        self.close()
        return self.dir

    def close(self) -> None:
        """Close the logs and the progress bar."""
        if self._bar is not None:
            self._bar.close()
        if self._writer is not None:
            self._writer.close()
            self._writer = None
        if self._scalars is not None:
            self._scalars.close()
            self._scalars = None


@contextmanager
def process_settings(threads: int | None) -> Iterator[Any]:
    """The process as training wants it, put back as it was afterwards.

    Threads: ``AdaptiveThreads`` (the cores other processes leave idle, or ``threads``). Dead
    ReLU units get zero gradients, so their Adam moments decay through the denormal range, where
    x86 arithmetic is ~100x slower: measured, each Adam step took 5x longer. Flush them to zero,
    as TensorFlow does on CPU (threads started later inherit it).
    """
    from rrls.agents.threads import AdaptiveThreads

    flushed = _flush_denormal_enabled()
    torch.set_flush_denormal(True)
    adaptive = AdaptiveThreads(threads)
    try:
        yield adaptive
    finally:
        adaptive.restore()
        torch.set_flush_denormal(flushed)


def _flush_denormal_enabled() -> bool:
    """Whether this thread flushes float32 denormals to zero (torch has no getter for it)."""
    tiny = torch.tensor([1e-37], dtype=torch.float32)
    return bool((tiny * 1e-3).item() == 0.0)


def _truncate_scalars(path: Path, step: int) -> None:
    """Drop curve rows written after the checkpoint being resumed (they will be redone)."""
    if not path.exists():
        return
    lines = path.read_text(encoding="utf-8").splitlines(keepends=True)
    rows = [ln for ln in lines[1:] if ln.endswith("\n") and int(ln.split(",", 1)[0]) <= step]
    keep = lines[:1] + rows
    atomic_write_bytes(path, "".join(keep).encode())


def _jsonable(fields: dict[str, Any]) -> dict[str, Any]:
    return {k: (list(v) if isinstance(v, tuple) else v) for k, v in fields.items()}


RUN_FILES = ("checkpoint.pt", "policy.npz", "adversary.npz", "actor.pt", "run.json", "scalars.csv")


def _finished_steps(run_dir: Path) -> int | None:
    """The steps of the finished run in ``run_dir`` (policy and run.json written), else None."""
    try:
        if (run_dir / "policy.npz").exists():
            return int(json.loads((run_dir / "run.json").read_text())["steps"])
    except (OSError, ValueError, KeyError):
        pass
    return None


def _remove_run_files(run_dir: Path) -> None:
    """``--overwrite``: what a previous run left (its checkpoint, policies, logs)."""
    import shutil

    for name in RUN_FILES:
        (run_dir / name).unlink(missing_ok=True)
    shutil.rmtree(run_dir / "tb", ignore_errors=True)


def _remove_temporary_files(run_dir: Path) -> None:
    """Temporary files of atomic writes killed half-way (``.checkpoint.pt.XXXX.tmp``)."""
    for path in run_dir.glob(".*.tmp"):
        path.unlink(missing_ok=True)


class _NullWriter:
    def add_scalar(self, *args: Any, **kwargs: Any) -> None:
        pass

    def close(self) -> None:
        pass
