"""A training run's side of the disk: the run directory and its checkpoints (``Run``), the
metrics sinks (``Metrics``: TensorBoard, ``scalars.csv``, Weights & Biases with ``--track``, a
progress bar) and the periodic evaluation (``PeriodicEvaluation``).

Checkpoints are taken every ``checkpoint_every`` steps, mid-episode, and at Ctrl-C (at the end
of the step it came in: ``rrls.agents.boundary``): they hold each run's slice of the learner's
state, the loop's generator and the episode in progress (replayed on resume), so a resumed run
continues exactly as the uninterrupted one (tested bit for bit), and the executions so far (the
machine and commit of each process that trained the run, listed in ``run.json``). They are
written atomically, sealed by a SHA-256 (a damaged file is refused with a one-line error naming
it) and loaded with ``torch.load(weights_only=True)``. File names: ``rrls.rundir``.
"""

from __future__ import annotations

import io
import json
import os
import time
from dataclasses import asdict
from pathlib import Path
from typing import Any

import numpy as np
import torch

from rrls import files, rundir
from rrls.agents.config import Diverged, Interrupted, TrainConfig, benchmark_set
from rrls.agents.hparams import jsonable
from rrls.files import loads_json
from rrls.physics import physics_label
from rrls.provenance import machine, source_commit

#: stop a run right after the checkpoint at or past this step, as if killed (fault injection)
STOP_AT_ENV = "RRLS_STOP_AT"
#: a checkpoint's flag: written at Ctrl-C (True) or on the periodic schedule
INTERRUPTED_KEY = "interrupted"
#: a checkpoint's record of the processes that trained the run so far (``execution``)
EXECUTIONS_KEY = "executions"


def execution(first_step: int) -> dict[str, Any]:
    """One process's share of a run: the step it started from, the machine and the rrls commit.
    A run resumed on another CPU kind trains on in other kernels (its last bits, then its
    trajectory, drift), so ``run.json`` lists every execution, not only the last one's machine."""
    return {"first_step": first_step, "machine": machine(), "commit": source_commit()}


def earlier_executions(state: dict[str, Any], where: Path) -> list[dict[str, Any]]:
    """The executions the checkpoint ``where`` records; one of unknown machine and commit for a
    checkpoint written before they were recorded (its run trained from step 0 somewhere)."""
    if EXECUTIONS_KEY not in state:
        return [{"first_step": 0, "machine": None, "commit": None}]
    found = loads_json(state[EXECUTIONS_KEY], f"{where}: its executions")
    if not isinstance(found, list) or not all(isinstance(e, dict) for e in found):
        raise ValueError(
            f"cannot resume from {where}: its executions are not a list of objects; pass "
            "--overwrite to start again"
        )
    return found


def versions() -> dict[str, str]:
    """The evaluation's version record plus torch (saved with every policy)."""
    from rrls.provenance import versions as evaluation_versions

    return {**evaluation_versions(), "torch": torch.__version__}


class Metrics:
    """Where a run's scalars go: TensorBoard (``tb/``), ``scalars.csv`` (the curves as a plain
    table, for reports that must not parse TensorBoard files), W&B when ``track``."""

    def __init__(self, config: TrainConfig, directory: Path, step: int) -> None:
        self.config, self.dir, self.start = config, directory, step
        self.csv_path = directory / rundir.SCALARS
        self._csv: Any = None
        self._tb: Any = None
        self._wandb: Any = None
        if config.track:
            try:
                import wandb
            except ImportError:
                raise ValueError("--track logs to Weights & Biases: pip install wandb") from None
            try:
                self._wandb = wandb.init(
                    project=config.wandb_project,
                    name=directory.name,
                    config=asdict(config),
                    dir=str(directory),
                    resume="allow",
                    reinit=True,
                )
            except Exception as err:  # noqa: BLE001 - no login, no network...: one line
                reason = (str(err).strip().splitlines() or [type(err).__name__])[0]
                raise ValueError(
                    f"--track: Weights & Biases did not start ({reason}); log in with "
                    "`wandb login` (or set WANDB_API_KEY), or log offline with WANDB_MODE=offline"
                ) from None

    def log(self, values: dict[str, float], step: int) -> None:
        """TensorBoard (and W&B) only (losses: frequent, not part of the curves table)."""
        if self._tb is None:
            try:
                from torch.utils.tensorboard import SummaryWriter
            except ImportError:  # tensorboard is part of the `train` extra
                self._tb = False
            else:
                self._tb = SummaryWriter(
                    str(self.dir / rundir.TENSORBOARD), purge_step=self.start or None
                )
        if self._tb:
            for key, value in values.items():
                self._tb.add_scalar(key, float(value), step)
        if self._wandb is not None:
            self._wandb.log({k: float(v) for k, v in values.items()}, step=step)

    def record(self, values: dict[str, float], step: int) -> None:
        """``log`` plus a row per value in ``scalars.csv``."""
        self.log(values, step)
        if self._csv is None:
            new = not self.csv_path.exists()
            self._csv = open(self.csv_path, "a", encoding="utf-8")
            if new:
                self._csv.write("step,metric,value\n")
        self._csv.writelines(f"{step},{key},{float(value)!r}\n" for key, value in values.items())

    def flush(self) -> None:
        """Write the curves out and seal them (at every checkpoint: a resume checks them)."""
        if self._csv is not None:
            self._csv.flush()
            files.seal(self.csv_path)

    def close(self) -> None:
        if self._tb:
            self._tb.close()
        self._tb = None
        if self._csv is not None:
            self._csv.close()
            self._csv = None
            files.seal(self.csv_path)
        if self._wandb is not None:
            self._wandb.finish()
            self._wandb = None


class PeriodicEvaluation:
    """A run's nominal return (and, with ``eval_mesh``, the coarse-mesh worst/average case) of
    its ``MLPPolicy``, every ``eval_every`` steps: the protocols planned once, the envs kept
    (rows as ``rrls.evaluation.evaluate`` gives them, 5 episodes seeded from 10 000)."""

    SEED = 10_000

    def __init__(self, config: TrainConfig) -> None:
        self.config = config
        self._evaluators: dict[str, Any] | None = None

    def _plan(self, policy: Any) -> dict[str, Any]:
        from rrls.envs import resolve
        from rrls.evaluation.protocol import Protocol
        from rrls.evaluation.stack import policy_view
        from rrls.evaluation.static import Evaluator

        config, view = self.config, policy_view(policy)
        physics = config.physics
        nominal = Protocol(
            "nominal", episodes=config.eval_episodes, seed=self.SEED, physics=physics
        )
        evaluators = {"nominal": Evaluator(config.task, nominal, view)}
        if config.eval_mesh > 0:
            family = resolve(config.task, config.uncertainty).family
            mesh_set = benchmark_set(config.task) if family == "force" else config.uncertainty
            mesh = Protocol(
                mesh_set, mesh=config.eval_mesh, episodes=1, seed=self.SEED, physics=physics
            )
            evaluators["mesh"] = Evaluator(config.task, mesh, view)
        return evaluators

    def __call__(self, policy: Any) -> dict[str, float]:
        if self._evaluators is None:
            self._evaluators = self._plan(policy)
        scores = {"eval/nominal_return": self._evaluators["nominal"](policy).average_case}
        if "mesh" in self._evaluators:
            mesh = self._evaluators["mesh"](policy)
            scores.update(
                {"eval/worst_case": mesh.worst_case, "eval/average_case": mesh.average_case}
            )
        return scores

    def close(self) -> None:
        if self._evaluators is not None:
            self._evaluators["nominal"].close()  # one engine cache for both
            self._evaluators = None


def read_checkpoint(path: Path) -> dict[str, Any]:
    """A run's checkpoint, or a one-line error naming the file when it cannot be used."""
    data = files.read_sealed(path)  # damaged bytes: refused here
    try:
        state = torch.load(io.BytesIO(data), weights_only=True, map_location="cpu")
    except Exception as err:  # noqa: BLE001 - not a checkpoint: all say the same
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


class Run:
    """One run's directory: fresh start / resume / overwrite policy, checkpoints, final files."""

    def __init__(self, config: TrainConfig, resume: bool, hyper: Any) -> None:
        self.config, self.hyper = config, hyper
        self.dir = Path(config.out)
        self.checkpoint_path = self.dir / rundir.CHECKPOINT
        self.step = self.episodes = 0
        self.finished = False
        self.metrics: Metrics | None = None
        self._bar: Any = None
        self._evaluation: PeriodicEvaluation | None = None
        done = rundir.finished_steps(self.dir)
        if config.overwrite:
            rundir.remove_run_files(self.dir)
        elif done is not None:
            if not resume:
                raise FileExistsError(
                    f"{self.dir} holds a finished run ({done} steps): pass --overwrite to "
                    "replace it, --resume with more --steps to extend it, or another --out"
                )
            if config.steps <= done:
                if self.checkpoint_path.exists():
                    self._check_identity(read_checkpoint(self.checkpoint_path))
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
        rundir.remove_temporary_files(self.dir)  # left by a write killed half-way
        self.resumed = resume and self.checkpoint_path.exists()
        if not self.resumed:  # a fresh start: curves of a run killed before its first
            rundir.remove_run_files(self.dir)  # checkpoint would otherwise be appended to
        self._last_checkpoint = self._last_eval = 0
        self.saved_step: int | None = None  # the step of the checkpoint this process wrote last
        self._t0, self._t0_step = time.perf_counter(), 0
        #: this process's share of the run and the earlier ones (``load``: a resumed run's)
        self.executions = [execution(0)]

    # -- checkpoints ------------------------------------------------------------------------
    def _check_identity(self, state: dict[str, Any]) -> None:
        saved = loads_json(state["config"], f"{self.checkpoint_path}: its config")
        if not isinstance(saved, dict):
            raise ValueError(
                f"cannot resume from {self.checkpoint_path}: its config is not an object; "
                "pass --overwrite to start again"
            )
        saved["physics"] = physics_label(saved.get("physics"))  # older: rrls-v5 (paper-v4 refused)
        current = self.config.identity(self.hyper)
        diff = [k for k in current if k != "hyper" and saved.get(k) != current[k]]
        diff += [
            k for k in current["hyper"] if saved.get("hyper", {}).get(k) != current["hyper"][k]
        ]
        if diff:

            def value(config: dict[str, Any], key: str) -> Any:
                return config.get(key, config.get("hyper", {}).get(key))

            what = "; ".join(
                f"{k} {value(saved, k)!r} (now {value(current, k)!r})" for k in sorted(diff)
            )
            raise ValueError(f"cannot resume {self.dir}: it was trained with {what}")

    def load(self) -> dict[str, Any] | None:
        """The saved state when resuming (checked against this config), else ``None``."""
        if not self.resumed:
            return None
        state = read_checkpoint(self.checkpoint_path)
        self._check_identity(state)
        if int(state["step"]) > self.config.steps:
            raise ValueError(
                f"cannot resume from {self.checkpoint_path}: it is at step {int(state['step'])}, "
                f"beyond --steps {self.config.steps}"
            )
        self.step, self.episodes = int(state["step"]), int(state["episodes"])
        # a checkpoint written at Ctrl-C keeps the periodic ones where they were due
        self._last_checkpoint = int(state.get("last_checkpoint", self.step))
        self._last_eval = int(state["last_eval"])
        self.executions = [*earlier_executions(state, self.checkpoint_path), execution(self.step)]
        rundir.truncate_scalars(self.dir / rundir.SCALARS, self.step)
        return state

    def steps_to_checkpoint(self) -> int:
        """Env steps until the next checkpoint falls due."""
        return max(1, self.config.checkpoint_every - (self.step - self._last_checkpoint))

    def steps_to_eval(self) -> int | None:
        """Env steps until the next periodic evaluation falls due (None: none planned)."""
        every = self.config.eval_every
        return max(1, every - (self.step - self._last_eval)) if every > 0 else None

    def checkpoint_due(self) -> bool:
        return self.step - self._last_checkpoint >= self.config.checkpoint_every

    def save(self, state: dict[str, Any], interrupted: bool = False) -> None:
        """Write the checkpoint atomically, sealed by its checksum; ``interrupted``: at Ctrl-C,
        off the periodic schedule (which a resume keeps: the same steps as an unbroken run)."""
        if not interrupted:
            self._last_checkpoint = self.step
        state = {
            **state,
            "step": self.step,
            "episodes": self.episodes,
            "last_eval": self._last_eval,
            "last_checkpoint": self._last_checkpoint,
            INTERRUPTED_KEY: interrupted,
            EXECUTIONS_KEY: json.dumps(self.executions),
            "config": json.dumps(self.config.identity(self.hyper)),
        }
        buf = io.BytesIO()
        torch.save(state, buf)
        if self.metrics is not None:  # the curves reach at least as far as the checkpoint
            self.metrics.flush()
        files.write_sealed(self.checkpoint_path, buf.getvalue())
        self.saved_step = self.step

    def check_stop(self) -> None:
        """Stop as if killed, right after the checkpoint at or past ``$RRLS_STOP_AT`` (fault
        injection: how the tests kill a run at a known step; a user can cut a run in pieces the
        same way and ``--resume`` it)."""
        stop = os.environ.get(STOP_AT_ENV)
        if stop and self.step >= int(stop):
            raise Interrupted(f"stopped at step {self.step} ({STOP_AT_ENV}={stop})")

    # -- logs and evaluation ----------------------------------------------------------------
    def _metrics(self) -> Metrics:
        if self.metrics is None:
            self.metrics = Metrics(self.config, self.dir, self.step)
        return self.metrics

    def log(self, values: dict[str, float]) -> None:
        self._metrics().log(values, self.step)

    def progress(self, group: int = 1) -> Any:
        """The run's progress (``rrls._progress``: a bar on a terminal; ``progress=True``, as
        ``rrls train`` sets it, plain lines elsewhere)."""
        from rrls._progress import progress_bar

        self._bar = progress_bar(
            self.config.steps * group,
            initial=self.step * group,
            unit="step",
            desc=f"{self.config.algo} {self.config.task}"
            + (f" ({group} runs)" if group > 1 else ""),
            shown=self.config.progress,
            smoothing=0.05,
        )
        self._t0, self._t0_step = time.perf_counter(), self.step
        return self._bar

    def episode_end(self, episode_return: float, length: int, **extra: float) -> None:
        self.episodes += 1
        elapsed = time.perf_counter() - self._t0
        sps = (self.step - self._t0_step) / elapsed if elapsed > 0 else 0.0
        self._metrics().record(
            {
                "charts/episode_return": episode_return,
                "charts/episode_length": length,
                "charts/steps_per_second": sps,
                **extra,
            },
            self.step,
        )
        if self._bar is not None:
            self._bar.set_postfix(ret=f"{episode_return:.1f}", refresh=False)

    def eval_due(self) -> bool:
        every = self.config.eval_every
        return every > 0 and self.step - self._last_eval >= every

    def evaluate(self, policy: Any) -> dict[str, float]:
        self._last_eval = self.step
        if self._evaluation is None:
            self._evaluation = PeriodicEvaluation(self.config)
        scores = self._evaluation(policy)
        self._metrics().record(scores, self.step)
        return scores

    def metadata(self, env: Any) -> dict[str, Any]:
        """What the saved policies record (``rrls evaluate RUN_DIR`` reads task and set)."""
        return {
            "algorithm": self.config.algo,
            "task": self.config.task,
            "uncertainty": self.config.uncertainty,
            **({"split": self.config.split} if self.config.split else {}),
            "physics": self.config.physics,
            # what stepped the training envs (the evaluations' physics is ``physics``, on CPU)
            **({"simulator": self.config.simulator} if self.config.simulator != "mujoco" else {}),
            "obs_dim": env.observation_space.shape[0],
            "hidden": list(getattr(self.hyper, "hidden", ())),
            "seed": self.config.seed,
            "run_dir": str(self.dir),
            "versions": versions(),
            "provenance": {
                "commit": source_commit(),
                "machine": machine(),
                "device": self.config.device,
            },
        }

    # -- the end ----------------------------------------------------------------------------
    def finish(self, policies: dict[str, Any], summary: dict[str, Any]) -> Path:
        """Save the final policies (``policy.npz``; ``adversary.npz`` for two-player runs, for
        the dynamic evaluation, Table 6) and ``run.json`` (last: it marks the run finished),
        whose ``provenance`` lists every execution that trained the run."""
        for name, policy in policies.items():
            policy.save(self.dir / (rundir.POLICY if name == "policy" else f"{name}.npz"))
        metadata = policies["policy"].metadata
        provenance = {**metadata.get("provenance", {}), EXECUTIONS_KEY: self.executions}
        files.write_checked_json(
            self.dir / rundir.RUN_JSON,
            {
                **metadata,
                "provenance": provenance,
                # the run described once: its settings with the algorithm's resolved Config
                # (every hyper-parameter, not only the overrides), as resume compares them
                "config": jsonable({**asdict(self.config), "hyper": asdict(self.hyper)}),
                **summary,
            },
        )
        self.close()
        return self.dir

    def close(self) -> None:
        """Close the logs, the progress bar and the periodic evaluation's envs."""
        if self._evaluation is not None:
            self._evaluation.close()
        if self._bar is not None:
            self._bar.close()
        if self.metrics is not None:
            self.metrics.close()
            self.metrics = None


def export_policies(learner: Any, k: int, metadata: dict[str, Any]) -> dict[str, Any]:
    """Run ``k``'s exported policies, their metadata completed with the run's; a policy with
    NaN/inf weights is refused (``Diverged``), never written."""
    out = learner.export(k)
    for name, policy in out.items():
        arrays = [*getattr(policy, "weights", []), *getattr(policy, "biases", [])]
        if not all(np.all(np.isfinite(a)) for a in arrays):
            seed = metadata.get("seed")
            raise Diverged(
                f"training stopped: the {name} of seed {seed} has non-finite (NaN/inf) weights; "
                "it is not written (the learner diverged: lower its learning rate or check its "
                "update)"
            )
        own = dict(policy.metadata)
        policy.metadata = {**metadata, "act_dim": policy.act_dim, **own}
        if name != "policy":
            policy.metadata.setdefault("role", name)
    return out
