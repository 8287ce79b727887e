"""What a benchmark is: a grid of runs (algorithm × task × seed) sharing one protocol.

A ``Spec`` is written to ``DIR/benchmark.json``. Re-running over the same directory must use the
same *protocol* (steps, mesh, episodes, set, hyper-parameters): anything else would mix numbers
that are not comparable, so it is refused with the fields that differ. The *grid* (algorithms,
tasks, seeds) may grow: the stored spec becomes the union and only the new runs are trained.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, fields
from functools import cached_property
from typing import Any

from rrls.algorithms import (
    ALGORITHMS,
    algorithm_info,
    algorithm_key,
    built_in,
    paper_five,
    warmup,
)
from rrls.evaluation.protocol import Protocol, check_episodes
from rrls.physics import SIMULATORS, V5, is_paper, physics_label

ALGOS = paper_five()  # the paper's five (the presets' default)
# every built-in algorithm (rrls.algorithms, the table); plug-ins are accepted by name (entry
# point group "rrls.algorithms", or a registered row) or as package.module:Learner
BUILT_IN = built_in()
PAPER_TASKS = ("ant", "halfcheetah", "hopper", "humanoidstandup", "walker")
GRID = ("algos", "tasks", "seeds")  # may grow between invocations
#: do not change the numbers' meaning (device: docs/performance.md; recheck: statistics beside)
LABELS = ("preset", "device", "recheck")


class SpecError(ValueError):
    """A benchmark specification that cannot run (the CLI prints it on one line, exit 2)."""


@dataclass(frozen=True)
class Spec:
    """One benchmark: every run trains, evaluates over the mesh, and (RARL, NR-MDP) plays its
    own adversary. ``uncertainty`` is the evaluation set and the training set of DR and M2TD3;
    RARL trains against its force adversary (the paper's), TD3 and NR-MDP ignore it."""

    algos: tuple[str, ...] = ALGOS
    tasks: tuple[str, ...] = PAPER_TASKS
    uncertainty: str = "3d"
    seeds: tuple[int, ...] = tuple(range(10))
    steps: int = 5_000_000
    #: random warm-up steps of every run; None: each algorithm's own (its row in
    #: ``rrls.algorithms``: 25 000 for the TD3 family, M2TD3's authors' 100 000)
    learning_starts: int | None = None
    eval_every: int = 50_000  # periodic nominal evaluation during training (curves)
    eval_episodes: int = 5
    eval_mesh: int = 0  # >0: periodic evaluations also over a coarse mesh (eval/worst_case)
    mesh: int = 10
    #: whether the mesh reaches the set's upper bounds (``np.linspace``); False is the paper's
    #: mesh (``np.arange`` from the lower bound in steps of (high - low) / mesh, the upper bound
    #: never reached); None: the physics' default (False on the paper's physics, else True:
    #: what a benchmark.json written before this field evaluated on)
    endpoint: bool | None = None
    episodes: int = 5
    dynamic_episodes: int = 10
    learning_rate: float | None = None  # None: the paper's 3e-4
    normalize_omega: bool = False
    hidden: tuple[int, ...] = (256, 256)
    batch_size: int | None = None  # None: the paper's (TD3 256, M2TD3 100)
    checkpoint_every: int = 50_000
    eval_seed: int = 0
    preset: str = "paper"
    device: str = "cpu"
    #: which physics trains and evaluates every run (``rrls.physics``: v5 or paper)
    physics: str = V5
    #: RARL plays TC-RMDP's game: its adversary moves each parameter by at most this much per
    #: step, in raw parameter units (``rrls.wrappers.tc_rmdp``); None: RARL's own game
    rate_limit: float | None = None
    #: the rate-limited game: ``tc`` (the authors') or ``target`` (rrls's earlier one; what a
    #: benchmark.json written before ``rate_game`` existed played)
    rate_game: str = "tc"
    #: the RARL protagonist of the TC-RMDP game: vanilla, stacked or oracle
    observe: str = "vanilla"
    #: a train/test split of the set (``extrapolation:F``): every run trains on the inner box,
    #: the evaluation covers the whole set and the report gives in/out of distribution apart
    split: str | None = None
    #: what steps the training envs: ``mujoco`` (CPU MuJoCo) or ``warp`` (the task's MuJoCo
    #: Warp twin on ``device``); every evaluation stays on CPU MuJoCo
    simulator: str = "mujoco"
    #: each run's worst case also rechecked with fresh episodes (``rrls.evaluation.recheck``);
    #: None: not computed. Not binding: it adds statistics and changes none of the mesh's rows
    recheck: Any = None

    def __post_init__(self) -> None:
        if isinstance(self.recheck, dict):
            from rrls.evaluation.recheck import Recheck

            try:
                object.__setattr__(self, "recheck", Recheck.from_json(self.recheck))
            except (TypeError, ValueError) as err:
                raise SpecError(str(err)) from None

    def runs(self) -> list[RunKey]:
        """Every (algorithm, task, seed) of the grid, in a stable order: seed by seed, so that a
        benchmark stopped part-way (or produced in pieces) has every algorithm's first seeds."""
        return [RunKey(a, t, s) for t in self.tasks for s in self.seeds for a in self.algos]

    def train_set(self, algo: str) -> str:
        """The set a run trains on: ``uncertainty`` for every algorithm (paper §5 trains every
        baseline on the 3D set; RARL's adversary then picks the parameters every step)."""
        return self.uncertainty

    @cached_property
    def protocol(self) -> Protocol:
        """The final evaluation's protocol, built once: what every run and submitted policy of
        this benchmark is evaluated under (the mesh, the dynamic evaluation's episodes, the
        rate-limited game); ``benchmark.json`` stores its fields flat beside the grid's."""
        return Protocol(
            self.uncertainty,
            mesh=self.mesh,
            endpoint=self.endpoint,
            episodes=self.episodes,
            seed=self.eval_seed,
            physics=self.physics,
            split=self.split or None,
            dynamic_episodes=self.dynamic_episodes,
            rate_limit=self.rate_limit,
            rate_game=self.rate_game,
            recheck=self.recheck,
        )

    def hyperparameters(self, algo: str) -> dict[str, Any]:
        """The preset's overrides of ``algo``'s paper hyper-parameters (``TrainConfig.hyper``)."""
        hyper: dict[str, Any] = {
            "learning_starts": self.warmup(algo),
            "hidden": tuple(self.hidden),
        }
        if self.learning_rate is not None and algo in ALGOS:  # TD3's rate (SAC has two)
            hyper["learning_rate"] = self.learning_rate
        if self.batch_size is not None:
            hyper["batch_size"] = self.batch_size
        info = algorithm_info(algo)
        if info is not None and info.options is not None:  # its own options (its row says)
            hyper.update(info.options(self))
        return hyper

    def warmup(self, algo: str) -> int:
        """``algo``'s random warm-up steps in this benchmark (at most its steps)."""
        steps = warmup(algo) if self.learning_starts is None else self.learning_starts
        return min(steps, self.steps)

    def binding_fields(self) -> dict[str, Any]:
        """The fields two invocations over one directory must agree on (``simulator`` only
        when it is not CPU MuJoCo: a benchmark.json written before it reads as the same)."""
        out = {k: v for k, v in self.to_json().items() if k not in GRID + LABELS}
        if out.get("simulator") == "mujoco":
            del out["simulator"]
        return out

    def to_json(self) -> dict[str, Any]:
        out = {k: list(v) if isinstance(v, tuple) else v for k, v in asdict(self).items()}
        if out["recheck"] is None:  # a benchmark.json written before it reads the same
            del out["recheck"]
        return out

    def fingerprints(self) -> dict[str, str]:
        """What a run's ``result.json`` records of the benchmark it ran in: ``protocol``, its
        evaluation protocol's fingerprint (every run, submitted ones too), and ``benchmark``,
        the fingerprint of every field two invocations must agree on (trained runs). Runs of
        one benchmark produced in pieces on several machines share both."""
        from rrls._io import json_fingerprint

        return {
            "protocol": self.protocol.fingerprint(),
            "benchmark": json_fingerprint(self.binding_fields()),
        }

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> Spec:
        known = {f.name for f in fields(cls)}
        kw = {k: tuple(v) if isinstance(v, list) else v for k, v in data.items() if k in known}
        kw["physics"] = physics_label(kw.get("physics"))  # older labels read as today's
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


PRESETS: dict[str, dict[str, Any]] = {
    # Seconds, for tests: every code path (5 algorithms, curves, mesh, dynamic evaluation).
    "smoke": dict(
        algos=ALGOS,
        tasks=("invertedpendulum",),
        uncertainty="1d",
        seeds=(0,),
        steps=300,
        learning_starts=100,
        eval_every=150,
        eval_episodes=1,
        mesh=2,
        episodes=1,
        dynamic_episodes=1,
        learning_rate=1e-3,
        normalize_omega=True,
        hidden=(16, 16),
        batch_size=32,
        checkpoint_every=100,
    ),
    # ~18 minutes on 2 cores (a reduced protocol, NOT the paper's): InvertedPendulum, whose
    # nominal task TD3 learns on every seed within 25 k steps with 64-64 networks and Adam at
    # 1e-3 (measured per seed, docs/results/quick/README.md), 3 seeds x 30 k steps, so every
    # normalised score is against a TD3 that balances the pole.
    "quick": dict(
        algos=ALGOS,
        tasks=("invertedpendulum",),
        uncertainty="1d",
        seeds=(0, 1, 2),
        steps=30_000,
        learning_starts=1_000,
        eval_every=2_500,
        eval_episodes=5,
        eval_mesh=3,  # curves of the worst case too (3 pole masses, 1 episode each)
        mesh=10,
        episodes=5,
        dynamic_episodes=10,
        learning_rate=1e-3,
        normalize_omega=True,
        hidden=(64, 64),
        checkpoint_every=10_000,
    ),
    # A locomotion reference on rrls's physics, produced on 2-core machines in pieces: Hopper,
    # the paper's 3D set, its five baselines and hyper-parameters (256-256, batch 256, Adam 3e-4,
    # 25 k random steps), 3 seeds x 200 k steps (the paper: 10 x 5 M), the paper's mesh
    # (10 points per dimension) with 2 episodes per point (the paper: 5). 20-25 min a TD3 run on
    # an idle core (7.7 h for the 15 runs); docs/results/hopper/ is its shipped result,
    # `--reference hopper` its numbers.
    "hopper": dict(
        algos=ALGOS,
        tasks=("hopper",),
        uncertainty="3d",
        seeds=(0, 1, 2),
        steps=200_000,
        eval_every=10_000,
        eval_episodes=5,
        mesh=10,
        endpoint=False,
        episodes=2,
        dynamic_episodes=10,
        checkpoint_every=25_000,
    ),
    # The locomotion reference where the agents have learned: HalfCheetah (the paper's widest
    # robust gap, its Table 7), the paper's 3D set (world friction 0.1-4, torso mass 0.1-7,
    # back-thigh mass 0.1-3), its five baselines and hyper-parameters, 5 seeds x 300 k steps (TD3
    # measured first on 2 seeds: nominal return >= 4 000 by then, docs/results/halfcheetah/),
    # the paper's mesh (10 points per dimension, np.arange) x 5 episodes, as the paper.
    "halfcheetah": dict(
        algos=ALGOS,
        tasks=("halfcheetah",),
        uncertainty="3d",
        seeds=(0, 1, 2, 3, 4),
        steps=300_000,
        eval_every=10_000,
        eval_episodes=5,
        mesh=10,
        endpoint=False,
        episodes=5,
        dynamic_episodes=10,
        checkpoint_every=25_000,
    ),
    # The paper's protocol (§5): 5 algorithms × 5 tasks × 10 seeds, 5 M steps, 3D set, mesh 10.
    "paper": dict(
        algos=ALGOS,
        tasks=PAPER_TASKS,
        uncertainty="3d",
        seeds=tuple(range(10)),
        steps=5_000_000,
        eval_every=50_000,
        eval_episodes=5,
        mesh=10,
        endpoint=False,
        episodes=5,
        dynamic_episodes=10,
    ),
}


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


def make_spec(preset: str = "paper", **overrides: Any) -> Spec:
    """The preset with explicit options on top (``None`` means "not given"), validated.

    ``algos``/``tasks`` may be comma-separated strings; ``seeds`` is a count (seeds 0..N-1).
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
    values.update(given)
    try:
        values["physics"] = physics_label(values.get("physics"))
    except ValueError as err:
        raise SpecError(str(err)) from None
    values["tasks"] = tuple(dict.fromkeys(_task_key(t) for t in values["tasks"]))
    values["algos"] = tuple(dict.fromkeys(algorithm_key(a) for a in values["algos"]))
    if values.get("split"):  # canonical (extrapolation:0.5), so two spellings are one protocol
        from rrls.envs import training_split

        try:
            values["split"] = training_split(
                values["tasks"][0], values["uncertainty"], values["split"]
            )
        except ValueError as err:
            raise SpecError(str(err)) from None
    spec = Spec(**values)
    validate(spec)
    return spec


def _task_key(task: str) -> str:
    from rrls.tasks import get_task

    try:
        return get_task(task).key
    except ValueError as err:
        raise SpecError(str(err)) from None


def validate(spec: Spec) -> None:
    """Raise ``SpecError`` for anything that cannot run (before any process starts)."""
    from importlib.metadata import entry_points

    from rrls.envs import get_uncertainty_set
    from rrls.tasks import TASKS, get_task

    plugins = [ep.name for ep in entry_points(group="rrls.algorithms")]
    bad = [a for a in spec.algos if algorithm_info(a) is None]  # registered rows count too
    if bad:
        valid = ", ".join(dict.fromkeys([*ALGORITHMS, *plugins]))
        raise SpecError(f"unknown algorithm {bad[0]!r}; valid: {valid}, or package.module:Learner")
    if not spec.algos or not spec.tasks:
        raise SpecError("a benchmark needs at least one algorithm and one task")
    for task in spec.tasks:
        key = _task_key(task)
        if is_paper(spec.physics) and get_task(key).paper_id is None:
            valid = ", ".join(k for k, t in TASKS.items() if t.paper_id is not None)
            raise SpecError(
                f"task {key!r} has no paper physics; valid with --physics paper: {valid}"
            )
        for name in {spec.uncertainty, *(spec.train_set(a) for a in spec.algos)}:
            try:
                get_uncertainty_set(key, name)
            except ValueError as err:
                raise SpecError(str(err)) from None
        try:  # the final evaluation's size, refused now rather than after the training
            box = get_uncertainty_set(key, spec.uncertainty)
            check_episodes(box.mesh_size(spec.mesh), spec.episodes)
            check_episodes(1, spec.dynamic_episodes)
            if spec.eval_mesh:
                check_episodes(box.mesh_size(spec.eval_mesh), spec.eval_episodes)
        except ValueError as err:
            raise SpecError(f"{key}: {err}") from None
    for name in ("steps", "mesh", "episodes", "dynamic_episodes", "eval_episodes"):
        if getattr(spec, name) < 1:
            raise SpecError(f"--{name.replace('_', '-')} must be >= 1, got {getattr(spec, name)}")
    for name in ("learning_starts", "eval_every", "eval_mesh"):
        if (getattr(spec, name) or 0) < 0:
            raise SpecError(f"--{name.replace('_', '-')} must be >= 0, got {getattr(spec, name)}")
    if not spec.seeds or min(spec.seeds) < 0:
        raise SpecError("--seeds must be >= 1")
    if spec.checkpoint_every < 1:
        raise SpecError("checkpoint_every must be >= 1")
    if spec.split:
        from rrls.envs import training_split

        for task in spec.tasks:
            try:
                training_split(_task_key(task), spec.uncertainty, spec.split)
            except ValueError as err:
                raise SpecError(str(err)) from None
    if spec.rate_limit is not None:
        if not (isinstance(spec.rate_limit, (int, float)) and 0 < spec.rate_limit < float("inf")):
            raise SpecError(f"--rate-limit must be a finite number > 0, got {spec.rate_limit!r}")
        movers = [a.name for a in ALGORITHMS.values() if a.set_use == "adversary"]
        if not set(movers) & set(spec.algos):
            raise SpecError(
                "--rate-limit applies to an adversary moving the parameters: add "
                f"{' or '.join(movers)} to --algos"
            )
    from rrls.wrappers.tc_rmdp import OBSERVE, RATE_GAMES

    if spec.rate_game not in RATE_GAMES:
        raise SpecError(f"rate_game must be one of {', '.join(RATE_GAMES)}, got {spec.rate_game!r}")
    if spec.observe not in OBSERVE:
        raise SpecError(f"--observe must be one of {', '.join(OBSERVE)}, got {spec.observe!r}")
    if spec.simulator not in SIMULATORS:
        raise SpecError(f"--simulator must be {' or '.join(SIMULATORS)}, got {spec.simulator!r}")
    if spec.simulator == "warp":
        from rrls.twin.tasks import check_twin

        for algo in spec.algos:
            for task in spec.tasks:
                try:
                    check_twin(algo, _task_key(task), spec.physics)
                except ValueError as err:
                    raise SpecError(str(err)) from None
    if spec.observe != "vanilla" and (spec.rate_limit is None or spec.rate_game != "tc"):
        raise SpecError(
            f"--observe {spec.observe} is a protagonist of TC-RMDP's game: add --rate-limit R"
        )
