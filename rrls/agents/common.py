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
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch

from rrls._io import atomic_write_bytes, atomic_write_json
from rrls.agents.core import TD3Config

ALGOS = ("td3", "dr", "rarl", "nrmdp", "m2td3")


@dataclass
class TrainConfig:
    """One training run: the ``rrls train`` options (defaults reproduce the paper)."""

    algo: str = "td3"
    task: str = "hopper"
    uncertainty: str = "3d"
    steps: int = 5_000_000
    learning_starts: int = 25_000
    eval_every: int = 50_000
    seed: int = 0
    out: str = "runs/run"
    device: str = "cpu"
    hidden: tuple[int, ...] = (256, 256)
    batch_size: int | None = None  # None: the algorithm's paper value (TD3 256, M2TD3 100)
    learning_rate: float | None = None  # None: the paper's 3e-4 (actor and critics)
    normalize_omega: bool = False  # M2TD3: critics see ω rescaled to [-1, 1] (authors: raw)
    eval_episodes: int = 5
    eval_mesh: int = 0  # points per dimension of the coarse evaluation mesh (0: nominal only)
    checkpoint_every: int = 50_000
    max_episode_steps: int = 1000
    progress: bool | None = None
    threads: int | None = None  # torch threads; None: the cores other processes leave idle
    stop_at: int | None = None  # testing aid: stop (as if killed) at the first checkpoint >= this

    def identity(self) -> dict[str, Any]:
        """What must match for ``--resume`` (``steps`` may grow, logging options may change)."""
        keep = (
            "algo",
            "task",
            "uncertainty",
            "learning_starts",
            "seed",
            "hidden",
            "batch_size",
            "learning_rate",
            "normalize_omega",
            "max_episode_steps",
        )
        return {
            k: (list(v) if isinstance(v, tuple) else v)
            for k, v in asdict(self).items()
            if k in keep
        }

    def td3_config(self, batch_size: int = 256) -> TD3Config:
        """The TD3 hyper-parameters of this run: the paper's, with this run's overrides."""
        lr = self.learning_rate
        if lr is not None and not (np.isfinite(lr) and lr > 0):
            raise ValueError(f"learning_rate must be a positive finite number, got {lr}")
        return TD3Config(
            learning_starts=self.learning_starts,
            hidden=tuple(self.hidden),
            batch_size=self.batch_size or batch_size,
            learning_rate=lr if lr is not None else TD3Config.learning_rate,
        )


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


def make_env(task: str, kind: str = "robust", **kwargs: Any) -> Any:
    """A bare robust (or force) env of ``task``: the training loop handles the time limit."""
    from rrls.envs import FORCE_ENVS, ROBUST_ENVS
    from rrls.tasks import get_task

    key = get_task(task).key
    return (FORCE_ENVS if kind == "force" else ROBUST_ENVS)[key](**kwargs)


class Run:
    """The run directory: TensorBoard logs, progress bar, checkpoints, evaluation, final policy."""

    def __init__(self, config: TrainConfig, resume: bool = False) -> None:
        from rrls.tasks import get_task

        self.config = config
        self.task = get_task(config.task).key
        self.dir = Path(config.out)
        self.checkpoint_path = self.dir / "checkpoint.pt"
        if self.checkpoint_path.exists() and not resume:
            raise FileExistsError(
                f"{self.dir} already holds a run: pass --resume to continue it, or another --out"
            )
        self.dir.mkdir(parents=True, exist_ok=True)
        # Dead ReLU units get zero gradients, so their Adam moments decay through the denormal
        # range, where x86 arithmetic is ~100x slower: measured, each Adam step took 5x longer.
        # Flush them to zero, as TensorFlow does on CPU (threads started later inherit it);
        # ``close`` puts the process back as it was.
        self._flushed_before = _flush_denormal_enabled()
        torch.set_flush_denormal(True)
        from rrls.agents.threads import AdaptiveThreads

        self.threads = AdaptiveThreads(config.threads)
        self.scalars_path = self.dir / "scalars.csv"
        self._scalars: Any = None
        self.step = 0
        self.episodes = 0
        self._last_checkpoint = 0
        self._last_eval = 0
        self._writer: Any = None
        self._bar: Any = None
        self._t0 = time.perf_counter()
        self._t0_step = 0
        self.resumed = resume and self.checkpoint_path.exists()

    # -- checkpoints ------------------------------------------------------------------------
    def load(self) -> dict[str, Any] | None:
        """The saved state when resuming (checked against this config), else ``None``."""
        if not self.resumed:
            return None
        state = torch.load(self.checkpoint_path, weights_only=True, map_location="cpu")
        current = self.config.identity()
        # options added since the checkpoint was written count as their defaults
        saved = {**TrainConfig().identity(), **json.loads(state["config"])}
        diff = sorted(k for k in current if saved.get(k) != current[k])
        if diff:
            raise ValueError(
                f"cannot resume {self.dir}: it was trained with other {', '.join(diff)}"
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
            "config": json.dumps(self.config.identity()),
        }
        buf = io.BytesIO()
        torch.save(state, buf)
        if self._scalars is not None:  # the curves reach at least as far as the checkpoint
            self._scalars.flush()
        atomic_write_bytes(self.checkpoint_path, buf.getvalue())
        self._last_checkpoint = self.step
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

    def progress(self) -> Any:
        import sys

        from tqdm.auto import tqdm

        disable = (
            not sys.stderr.isatty() if self.config.progress is None else not self.config.progress
        )
        self._bar = tqdm(
            total=self.config.steps,
            initial=self.step,
            unit="step",
            desc=f"{self.config.algo} {self.task}",
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
        self.threads.poll()
        if self._bar is not None:
            self._bar.set_postfix(ret=f"{episode_return:.1f}", refresh=False)

    # -- evaluation -------------------------------------------------------------------------
    def eval_due(self) -> bool:
        every = self.config.eval_every
        return every > 0 and self.step - self._last_eval >= every

    def evaluate(self, actor: Any, metadata: dict[str, Any]) -> dict[str, float]:
        """Nominal return (and the coarse-mesh worst/average case) through the evaluation engine."""
        from rrls.evaluation import evaluate

        self._last_eval = self.step
        policy = actor.to_mlp_policy(metadata)
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
        return (
            self.config.uncertainty
            if self.config.uncertainty != "rarl"
            else "3d"
            if self.task != "invertedpendulum"
            else "2d"
        )

    # -- the end ----------------------------------------------------------------------------
    def finish(
        self,
        actor: Any,
        metadata: dict[str, Any],
        summary: dict[str, Any],
        adversary: Any = None,
        adversary_metadata: dict[str, Any] | None = None,
    ) -> Path:
        """Save the final policy (``policy.npz``, ``actor.pt``: tensors only) and ``run.json``;
        for two-player runs also the final adversary (``adversary.npz``, same safe format, its
        metadata saying which game and set it plays), for the dynamic evaluation (Table 6)."""
        if adversary is not None:
            adversary.to_mlp_policy({**metadata, **(adversary_metadata or {})}).save(
                self.dir / "adversary.npz"
            )
        actor.to_mlp_policy(metadata).save(self.dir / "policy.npz")
        buf = io.BytesIO()
        torch.save({k: v.cpu() for k, v in actor.state_dict().items()}, buf)
        atomic_write_bytes(self.dir / "actor.pt", buf.getvalue())
        atomic_write_json(
            self.dir / "run.json", {**metadata, "config": _jsonable(self.config), **summary}
        )
        self.close()
        return self.dir

    def close(self) -> None:
        """Close logs and give the process back its thread count and denormal mode."""
        if self._bar is not None:
            self._bar.close()
        if self._writer is not None:
            self._writer.close()
        if self._scalars is not None:
            self._scalars.close()
            self._scalars = None
        self.threads.restore()
        torch.set_flush_denormal(self._flushed_before)


def metadata(config: TrainConfig, obs_dim: int, act_dim: int, **extra: Any) -> dict[str, Any]:
    """What the saved policy records about itself (``rrls evaluate RUN_DIR`` reads ``task``)."""
    from rrls.tasks import get_task

    return {
        "algorithm": config.algo,
        "task": get_task(config.task).key,
        "uncertainty": config.uncertainty,
        "obs_dim": obs_dim,
        "act_dim": act_dim,
        "hidden": list(config.hidden),
        "seed": config.seed,
        "versions": versions(),
        **extra,
    }


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


def _jsonable(config: TrainConfig) -> dict[str, Any]:
    return {k: (list(v) if isinstance(v, tuple) else v) for k, v in asdict(config).items()}


class _NullWriter:
    def add_scalar(self, *args: Any, **kwargs: Any) -> None:
        pass

    def close(self) -> None:
        pass
