"""What a benchmark is: a grid of runs (algorithm × task × seed) sharing one protocol.

A ``Benchmark`` is a template run plus its ``Protocol``, written to ``DIR/benchmark.json`` (the
protocol as ``Protocol.to_json`` writes it; ``rrls.benchmark.benchfile``). Re-running over
the same directory must use the same settings (steps, hyper-parameters, every field of the
protocol): anything else would mix numbers that are not comparable, so it is refused with the
fields that differ. The *grid* (algorithms,
tasks, seeds) may grow: the stored spec becomes the union and only the new runs are trained.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field, fields, replace
from os import PathLike
from typing import Any

from rrls.algorithms import algorithm_info, algorithm_key, built_in, warmup
from rrls.benchmark.presets import ALGOS, PAPER_TASKS, PRESETS
from rrls.benchmark.validation import SpecError, check_protocol, task_key, validate
from rrls.deprecation import warn_deprecated
from rrls.evaluation.protocol import Protocol, Recheck
from rrls.wrappers.tc_rmdp import OBSERVE

__all__ = [
    "ALGOS",
    "BUILT_IN",
    "GRID",
    "LABELS",
    "LATER",
    "PAPER_TASKS",
    "PRESETS",
    "PROTOCOL_NAMES",
    "Benchmark",
    "RunKey",
    "SHARED_SETTINGS",
    "SpecError",
    "check_protocol",
    "make_spec",
    "read_protocol",
    "validate",
]

# every built-in algorithm (rrls.algorithms, the table); plug-ins are accepted by name (entry
# point group "rrls.algorithms", or a registered row) or as package.module:Learner
BUILT_IN = built_in()
GRID = ("algos", "tasks", "seeds")  # may grow between invocations
#: do not change the numbers' meaning (device: docs/performance.md; recheck: statistics beside)
LABELS = ("preset", "device", "recheck")


#: the ``Protocol``'s fields a ``Benchmark`` also takes flat (presets, options, ``benchmark.json``
#: files written before it held the protocol whole), under those files' names: the protocol's
#: ``seed`` is ``eval_seed`` there, beside the grid's training ``seeds``
PROTOCOL_NAMES = {
    **{name: name for name in Protocol.__dataclass_fields__ if name != "seed"},
    "eval_seed": "seed",
}
#: the settings a benchmark gives each of its runs as they are (``TrainConfig``'s fields of the
#: same names; the others ``Benchmark.run_settings`` derives per run)
SHARED_SETTINGS = (
    "steps",
    "eval_every",
    "eval_episodes",
    "eval_mesh",
    "checkpoint_every",
    "device",
    "physics",
    "split",
)
#: the protocol's fields a benchmark.json written before they could be given never held: the
#: flat view (and the benchmark fingerprint) names them only when they are not their default
LATER = {"disruptors": [], "schedule": None, "context": False, "max_episode_steps": None}


@dataclass(frozen=True, init=False)
class Benchmark:
    """One benchmark: a template run (the grid and the training settings) and the ``Protocol``
    every run and submitted policy is evaluated under. Every run trains, is evaluated over the
    protocol's mesh, and (RARL, NR-MDP) plays its own adversary. The protocol's set is the
    evaluation set and the training set of DR and M2TD3; RARL trains against its force adversary
    (the paper's), TD3 and NR-MDP ignore it.

    ``Benchmark(protocol=Protocol(...), ...)`` or, as presets and options give it, the protocol's
    fields flat (``Benchmark(mesh=2, eval_seed=0, ...)``, ``replace(spec, mesh=3)``): they replace
    those of ``protocol``. Read back, ``spec.mesh`` and the others are the protocol's."""

    algos: tuple[str, ...] = ALGOS
    tasks: tuple[str, ...] = PAPER_TASKS
    seeds: tuple[int, ...] = tuple(range(10))
    steps: int = 5_000_000
    #: random warm-up steps of every run; None: each algorithm's own (its row in
    #: ``rrls.algorithms``: 25 000 for the TD3 family, M2TD3's authors' 100 000)
    learning_starts: int | None = None
    eval_every: int = 50_000  # periodic nominal evaluation during training (curves)
    eval_episodes: int = 5
    eval_mesh: int = 0  # >0: periodic evaluations also over a coarse mesh (eval/worst_case)
    learning_rate: float | None = None  # None: the paper's 3e-4
    normalize_omega: bool = False
    hidden: tuple[int, ...] = (256, 256)
    batch_size: int | None = None  # None: the paper's (TD3 256, M2TD3 100)
    checkpoint_every: int = 50_000
    preset: str = "paper"
    device: str = "cpu"
    #: the RARL protagonist of the TC-RMDP game (its help: ``rrls benchmark --observe``'s)
    observe: str = field(
        default="vanilla",
        metadata={
            "choices": OBSERVE,
            "help": "with --rate-limit: RARL's protagonist is TC-RMDP's vanilla (the state), "
            "stacked (the previous state and action too) or oracle (the state and psi in "
            "[0, 1])",
        },
    )
    #: what steps the training envs: ``mujoco`` (CPU MuJoCo) or ``warp`` (the task's MuJoCo
    #: Warp twin on ``device``); every evaluation stays on CPU MuJoCo
    simulator: str = "mujoco"
    #: the final evaluation's protocol. Its set is a set's name, which every run also trains
    #: on; its ``physics`` trains and evaluates every run; its ``split`` (``extrapolation:F``)
    #: trains every run on the inner box; its ``rate_limit`` makes RARL play TC-RMDP's game
    #: (``rate_game``: ``tc``, the authors', or ``target``, rrls's earlier one); its
    #: ``max_episode_steps`` truncates training episodes too; its ``recheck`` is not binding
    #: (it adds statistics and changes none of the mesh's rows). The endpoint ``None``: the
    #: physics' default (False on the paper's physics, else True)
    protocol: Protocol = Protocol()

    def __init__(
        self, *, protocol: Protocol | Mapping[str, Any] | None = None, **given: Any
    ) -> None:
        flat = {PROTOCOL_NAMES[k]: given.pop(k) for k in list(given) if k in PROTOCOL_NAMES}
        if flat.get("split") == "":  # no split, as a benchmark.json may say it
            flat["split"] = None
        own = {f.name: f for f in fields(self) if f.name != "protocol"}
        unknown = sorted(set(given) - set(own))
        if unknown:
            raise TypeError(f"Benchmark got unknown field(s) {', '.join(unknown)}")
        for name, f in own.items():
            object.__setattr__(self, name, given.get(name, f.default))
        try:
            if protocol is None:
                protocol = Protocol()
            elif not isinstance(protocol, Protocol):
                protocol = Protocol.from_json(protocol)
            object.__setattr__(self, "protocol", protocol.replace(**flat) if flat else protocol)
        except (TypeError, ValueError) as err:
            raise SpecError(str(err)) from None

    # the protocol's fields, read as before the spec held it whole (the runs' names, training)
    @property
    def uncertainty(self) -> str:
        return self.protocol.uncertainty

    @property
    def mesh(self) -> int:
        return self.protocol.mesh

    @property
    def endpoint(self) -> bool | None:
        return self.protocol.endpoint

    @property
    def episodes(self) -> int:
        return self.protocol.episodes

    @property
    def dynamic_episodes(self) -> int:
        return self.protocol.dynamic_episodes

    @property
    def eval_seed(self) -> int:
        return self.protocol.seed

    @property
    def physics(self) -> str:
        return self.protocol.physics

    @property
    def split(self) -> str | None:
        return self.protocol.split

    @property
    def rate_limit(self) -> float | None:
        return self.protocol.rate_limit

    @property
    def rate_game(self) -> str:
        return self.protocol.rate_game

    @property
    def recheck(self) -> Recheck | None:
        return self.protocol.recheck

    def runs(self) -> list[RunKey]:
        """Every (algorithm, task, seed) of the grid, in a stable order: seed by seed, so that a
        benchmark stopped part-way (or produced in pieces) has every algorithm's first seeds."""
        return [RunKey(a, t, s) for t in self.tasks for s in self.seeds for a in self.algos]

    def train_set(self, algo: str) -> str:
        """The set a run trains on: ``uncertainty`` for every algorithm (paper §5 trains every
        baseline on the 3D set; RARL's adversary then picks the parameters every step)."""
        return self.uncertainty

    def simulator_for(self, task: str) -> str:
        """The simulator ``task``'s runs train on: the benchmark's, but CPU MuJoCo for a task
        without a Warp twin in a ``warp`` benchmark (HumanoidStandup's PGS solver), so that the
        paper's grid runs whole, the twin's tasks on the GPU beside it; evaluation is on CPU
        MuJoCo for every run either way."""
        if self.simulator != "warp":
            return self.simulator
        from rrls.twin.catalog import TWIN_TASKS

        return "warp" if task in TWIN_TASKS else "mujoco"

    def run_settings(self, run: RunKey, out: str | PathLike[str]) -> Any:
        """The ``TrainConfig`` of ``run``: the benchmark's shared settings (``SHARED_SETTINGS``,
        under the same names), the run's algorithm, task, seed and directory, its training set,
        simulator and hyper-parameters, the protocol's episode limit (None: the task's), and
        one thread (the benchmark runs a process per core)."""
        from rrls.agents.config import TrainConfig

        return TrainConfig(
            algo=run.algo,
            task=run.task,
            seed=run.seed,
            out=str(out),
            uncertainty=self.train_set(run.algo),
            simulator=self.simulator_for(run.task),
            max_episode_steps=self.protocol.max_episode_steps,
            threads=1,
            progress=False,
            hyper=self.hyperparameters(run.algo),
            **{name: getattr(self, name) for name in SHARED_SETTINGS},
        )

    def hyperparameters(self, algo: str) -> dict[str, Any]:
        """The preset's overrides of ``algo``'s paper hyper-parameters (``TrainConfig.hyper``)."""
        hyper: dict[str, Any] = {
            "learning_starts": self.warmup(algo),
            "hidden": tuple(self.hidden),
        }
        info = algorithm_info(algo)
        # --learning-rate sets the Config fields its row names (rate_fields): TD3's one rate on
        # the paper's five (presets.ALGOS, as before), none on SAC's rows (their two rates are
        # their own) nor on a plug-in's (a registered row names none unless it says so; a name
        # no row declares reads as a row of defaults: none)
        if info is not None and self.learning_rate is not None:
            hyper.update(dict.fromkeys(info.rate_fields, self.learning_rate))
        if self.batch_size is not None:
            hyper["batch_size"] = self.batch_size
        if info is not None and info.options is not None:  # its own options (its row says)
            hyper.update(info.options(self))
        return hyper

    def warmup(self, algo: str) -> int:
        """``algo``'s random warm-up steps in this benchmark (at most its steps)."""
        steps = warmup(algo) if self.learning_starts is None else self.learning_starts
        return min(steps, self.steps)

    def flat_json(self) -> dict[str, Any]:
        """The benchmark with its protocol's fields flat, as ``benchmark.json`` held it before it
        stored the protocol whole (``eval_seed``; disruptors, schedule, context and the episode
        limit only when given): what the report and reference files read, and what the
        benchmark fingerprint names, so that a benchmark written then keeps its fingerprint."""
        proto = self.protocol.to_json()
        out = {k: list(v) if isinstance(v, tuple) else v for k, v in self.to_json().items()}
        del out["protocol"]
        for name, key in PROTOCOL_NAMES.items():
            if key in proto and not (name in LATER and proto[key] == LATER[name]):
                out[name] = proto[key]
        return out

    def binding_fields(self) -> dict[str, Any]:
        """The fields two invocations over one directory must agree on (``simulator`` only
        when it is not CPU MuJoCo: a benchmark.json written before it reads as the same)."""
        out = {k: v for k, v in self.flat_json().items() if k not in GRID + LABELS}
        if out.get("simulator") == "mujoco":
            del out["simulator"]
        return out

    def to_json(self) -> dict[str, Any]:
        """``benchmark.json``: the template run's fields, and the protocol as its own JSON."""
        out: dict[str, Any] = {
            f.name: list(v) if isinstance(v, tuple) else v
            for f in fields(self)
            if f.name != "protocol"
            for v in (getattr(self, f.name),)
        }
        out["protocol"] = self.protocol.to_json()
        return out

    def fingerprints(self) -> dict[str, str]:
        """What a run's ``result.json`` records of the benchmark it ran in: ``protocol``, its
        evaluation protocol's fingerprint (every run, submitted ones too), and ``benchmark``,
        the fingerprint of every field two invocations must agree on (trained runs). Runs of
        one benchmark produced in pieces on several machines share both."""
        from rrls.files import json_fingerprint

        return {
            "protocol": self.protocol.fingerprint(),
            "benchmark": json_fingerprint(self.binding_fields()),
        }

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> Benchmark:
        """The inverse of ``to_json``; a file without ``protocol`` is one written before the
        benchmark held its protocol whole (its fields flat, every earlier format) and reads as
        the same benchmark."""
        kw = {k: tuple(v) if isinstance(v, list) else v for k, v in data.items()}
        if "protocol" not in kw:
            if kw.get("rate_limit") is not None and "rate_game" not in kw:
                kw["rate_game"] = "target"  # written before TC-RMDP's game: rrls's earlier one
        return cls(**kw)


@dataclass(frozen=True, order=True)
class RunKey:
    """One run of the grid; ``name`` is its directory under ``DIR/runs``."""

    algo: str
    task: str
    seed: int

    def name(self, uncertainty: str) -> str:
        return f"{self.algo}-{self.task}-{uncertainty}-seed{self.seed}"


def _csv(value: str, what: str) -> tuple[str, ...]:
    # names are case-insensitive; package.module:Class plug-ins keep their case
    items = tuple(
        dict.fromkeys(
            v.strip() if ":" in v else v.strip().lower() for v in value.split(",") if v.strip()
        )
    )
    if not items:
        raise SpecError(f"--{what} is empty")
    return items


def make_spec(preset: str = "paper", **overrides: Any) -> Benchmark:
    """The preset with explicit options on top (``None`` means "not given"), validated.

    ``algos``/``tasks`` may be comma-separated strings; ``seeds`` is a count (seeds 0..N-1).
    ``protocol`` (a ``Protocol``, its JSON object or a file holding it) replaces the preset's
    protocol whole; the protocol's fields given flat (``mesh``...) then override it.
    """
    if preset not in PRESETS:
        raise SpecError(f"unknown preset {preset!r}; valid: {', '.join(PRESETS)}")
    values: dict[str, Any] = {**PRESETS[preset], "preset": preset}
    given = {k: v for k, v in overrides.items() if v is not None}
    if isinstance(given.get("algos"), str):
        given["algos"] = _csv(given["algos"], "algos")
    if isinstance(given.get("tasks"), str):
        given["tasks"] = _csv(given["tasks"], "tasks")
    if "seeds" in given:
        n, first = given.pop("seeds"), given.pop("first_seed", 0) or 0
        if isinstance(n, int):
            if n < 1:
                raise SpecError(f"--seeds must be >= 1, got {n}")
            given["seeds"] = tuple(range(first, first + n))
        else:
            given["seeds"] = tuple(n)
    elif given.get("first_seed"):
        first = given.pop("first_seed")
        given["seeds"] = tuple(first + s for s in values["seeds"])
    given.pop("first_seed", None)
    if "steps" in given and "learning_starts" not in given:  # a short run still learns
        algos = given.get("algos", values["algos"])
        first = values.get("learning_starts")
        longest = max(warmup(a) for a in algos) if first is None else first
        if longest > given["steps"] // 5:
            given["learning_starts"] = min(longest, given["steps"] // 5)
    if "protocol" in given:  # the whole protocol: the preset's fields of it give way
        values = {k: v for k, v in values.items() if k not in PROTOCOL_NAMES}
        if isinstance(given["protocol"], (str, PathLike)):
            given["protocol"] = read_protocol(given["protocol"])
    values.update(given)
    _check_options(values)
    values["tasks"] = tuple(dict.fromkeys(task_key(t) for t in values["tasks"]))
    values["algos"] = tuple(dict.fromkeys(algorithm_key(a) for a in values["algos"]))
    spec = Benchmark(**values)
    if spec.split:  # canonical (extrapolation:0.5), so two spellings are one protocol
        from rrls.envs import training_split

        try:
            split = training_split(spec.tasks[0], spec.uncertainty, spec.split)
        except (TypeError, ValueError) as err:
            raise SpecError(str(err)) from None
        spec = replace(spec, split=split)
    validate(spec)
    return spec


def _check_options(values: Mapping[str, Any]) -> None:
    """Refuse the protocol's counts and rate limit as the options that give them are named
    (``--mesh``), before the ``Protocol`` refuses them by its own field names."""
    for name in ("mesh", "episodes", "dynamic_episodes"):
        value = values.get(name)
        if isinstance(value, int) and value < 1:
            raise SpecError(f"--{name.replace('_', '-')} must be >= 1, got {value}")
    rate = values.get("rate_limit")
    if rate is not None and not (isinstance(rate, (int, float)) and 0 < rate < float("inf")):
        raise SpecError(f"--rate-limit must be a finite number > 0, got {rate!r}")


def read_protocol(path: str | PathLike[str]) -> Protocol:
    """The ``Protocol`` in a JSON file (``Protocol.to_json``'s object: ``rrls benchmark
    --protocol FILE``); a file that is not one is a ``SpecError`` naming it."""
    from rrls.files import read_json

    try:
        return Protocol.from_json(read_json(path))
    except (OSError, TypeError, ValueError) as err:
        raise SpecError(f"--protocol {path}: {err}") from None


def __getattr__(name: str) -> Any:
    """``Spec``: :class:`Benchmark`'s former name (deprecated: one of four unrelated ``*Spec``
    classes of rrls; a benchmark is what it describes)."""
    if name == "Spec":
        warn_deprecated(
            "rrls.benchmark.grid.Spec is deprecated; use rrls.benchmark.grid.Benchmark "
            "(the same class)"
        )
        return Benchmark
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
