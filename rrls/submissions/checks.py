"""The first of ``rrls submit``'s three steps, whole: ``check_submission`` turns an ``Entry``
into a ``Checked`` before anything runs or changes — the benchmark submitted to (loaded or
started from a preset, a new task allowed to join, and re-read under the lock when the
submission is installed), the algorithm's name, the seed, the policy and adversary (loaded,
their shapes and identities, the policy prepared for the protocol) and the declared budget, each
failure one line, a ``SubmitError``. ``rrls.submissions.steps`` then evaluates and installs."""

from __future__ import annotations

import re
import shlex
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from rrls.algorithms import ALGORITHMS, plugin_entry_points
from rrls.benchmark import benchfile
from rrls.benchmark.grid import BUILT_IN, Benchmark, RunKey, SpecError
from rrls.evaluation.dynamic import GAME_SCHEMA, GAMES, check_adversary
from rrls.physics import is_paper
from rrls.schema import SchemaError

__all__ = [
    "BUDGET_KEYS",
    "Checked",
    "Entry",
    "RESERVED",
    "SubmitError",
    "benchmark_for",
    "check_budget",
    "check_declared_steps",
    "check_name",
    "check_new_task",
    "check_seed",
    "check_shapes",
    "check_submission",
    "env_shapes",
    "first_line",
    "grown_benchmark",
    "load_policy",
    "load_spec",
    "policy_identity",
    "preset_spec",
    "reserved_names",
]

#: names a submission may not take (in any case): every built-in algorithm, their display
#: names, and "paper" (the paper's published numbers in the report); installed plug-ins'
#: names are reserved too (``reserved_names``)
RESERVED = tuple(
    dict.fromkeys(
        [
            *BUILT_IN,
            *(a.display.lower() for a in ALGORITHMS.values() if a.name in BUILT_IN),
            "pr-mdp",
            "prmdp",
            "paper",
        ]
    )
)
_NAME = re.compile(r"^[A-Za-z][A-Za-z0-9_.+-]{0,39}$")
_NAME_RULE = "a letter, then up to 39 letters, digits or _ . + -"


class SubmitError(ValueError):
    """A submission that cannot be accepted (the CLI prints it on one line, exit status 2)."""


def reserved_names() -> tuple[str, ...]:
    """``RESERVED``, the registered rows of the algorithm table and the installed plug-in
    algorithms (entry point group ``rrls.algorithms``), lower-case."""
    rows = [n for a in ALGORITHMS.values() for n in (a.name.lower(), a.display.lower())]
    plugins = [name.lower() for name in plugin_entry_points()]
    return tuple(dict.fromkeys([*RESERVED, *rows, *plugins]))


def check_name(name: str) -> str:
    """``name`` if it can name a submitted algorithm, else ``SubmitError`` with the rules."""
    if not isinstance(name, str) or not _NAME.match(name):
        raise SubmitError(f"--algo {name!r} is not a valid algorithm name: {_NAME_RULE}")
    reserved = reserved_names()
    if name.lower() in reserved:
        what = (
            "a built-in algorithm"
            if name.lower() in RESERVED
            else "an installed plug-in"
            if name.lower() in {p.lower() for p in plugin_entry_points()}
            else "a registered algorithm"
        )
        raise SubmitError(
            f"--algo {name!r} is {what} (reserved: {', '.join(reserved)}; in any case); "
            f"choose another name: {_NAME_RULE}"
        )
    return name


def check_seed(seed: Any) -> int:
    """``seed`` as an int if it is one in ``0..MAX_SEED`` (``rrls.seeds``: the runs' 32-bit
    seeds), else ``SubmitError`` (one line)."""
    from rrls.seeds import MAX_SEED, seed_message

    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)):
        raise SubmitError(f"--seed: {seed_message(repr(seed))}")
    if not 0 <= int(seed) <= MAX_SEED:
        text = str(int(seed))
        shown = text if len(text) <= 24 else f"{text[:10]}...{text[-4:]} ({len(text)} digits)"
        raise SubmitError(f"--seed: {seed_message(shown)}")
    return int(seed)


def _shape_text(shape: tuple[int, ...]) -> str:
    return "(B, " + ", ".join(map(str, shape)) + ")"


def check_shapes(
    policy: Any, obs_shape: tuple[int, ...], act_shape: tuple[int, ...], what: str, task: str
) -> None:
    """Refuse (``SubmitError``, one line naming both shapes) a policy that does not map the
    task's observations to its actions — before any episode runs."""
    from rrls.evaluation.sources import policy_shapes

    declared = policy_shapes(policy)
    expected = (
        f"{task} has observations {_shape_text(obs_shape)} and actions {_shape_text(act_shape)}"
    )
    if declared is not None and declared != (obs_shape, act_shape):
        raise SubmitError(
            f"the {what} maps observations {_shape_text(declared[0])} to actions "
            f"{_shape_text(declared[1])}, but {expected}"
        )
    probe = np.zeros((2, *obs_shape))
    try:
        out = np.asarray(policy(probe))
    except Exception as err:  # noqa: BLE001 - any failure on the task's observations
        first = (str(err).strip().splitlines() or [type(err).__name__])[0]
        raise SubmitError(
            f"the {what} fails on observations {_shape_text(obs_shape)} ({expected}): {first}"
        ) from None
    if out.shape != (2, *act_shape):
        got = "(B, " + ", ".join(map(str, out.shape[1:])) + ")" if out.ndim else "a scalar"
        raise SubmitError(
            f"the {what} maps observations {_shape_text(obs_shape)} to actions {got}, "
            f"but {expected}"
        )


def check_new_task(root: Path, spec: Benchmark, key: str, add_task: bool) -> None:
    """Whether ``key`` may join ``spec``: only on purpose (``add_task``), and only in a
    submissions-only benchmark."""
    from rrls.envs import get_uncertainty_set
    from rrls.tasks import TASKS, get_task

    if is_paper(spec.physics) and get_task(key).paper_id is None:
        valid = ", ".join(k for k, t in TASKS.items() if t.paper_id is not None)
        raise SubmitError(f"task {key!r} has no paper physics; valid in this benchmark: {valid}")
    if spec.algos:  # a benchmark with baselines: only its tasks compare
        raise SubmitError(
            f"task {key!r} is not in the benchmark {root} (its tasks: "
            f"{', '.join(spec.tasks)}); add it with `rrls benchmark --out "
            f"{shlex.quote(str(root))} --tasks {','.join((*spec.tasks, key))} ...`"
        )
    if not add_task:
        raise SubmitError(
            f"task {key!r} is not in the benchmark {root} (its tasks: {', '.join(spec.tasks)}); "
            "--add-task adds it on purpose"
        )
    try:
        get_uncertainty_set(key, spec.uncertainty)
    except ValueError as err:
        raise SubmitError(str(err)) from None


#: budget keys rrls writes itself: the steps (``--steps``) and who declared them
BUDGET_KEYS = ("steps", "declared_by")


def check_budget(budget: dict[str, Any] | None) -> dict[str, str]:
    """The free-form budget as text, refusing the keys rrls writes itself (one line)."""
    out: dict[str, str] = {}
    for key, value in (budget or {}).items():
        name = str(key).strip()
        if not name or name in BUDGET_KEYS:
            raise SubmitError(
                f"--budget key {key!r} is reserved or empty (rrls writes {', '.join(BUDGET_KEYS)}: "
                "declare the steps with --steps); valid: any other KEY=VALUE"
            )
        if (
            value is None
            or isinstance(value, (dict, list, bool, np.bool_))
            or (isinstance(value, float) and not np.isfinite(value))
        ):
            raise SubmitError(
                f"--budget {name}={value!r}: valid: text or a finite number (not a bool or null)"
            )
        out[name] = str(value)
    return out


def check_declared_steps(meta: dict[str, Any]) -> None:
    """The policy's recorded training steps, if any, must be a whole number >= 0 (a bool, a
    negative or a fraction is refused in one line before the evaluation runs)."""
    value = meta.get("steps")
    if value is None:
        return
    ok = not isinstance(value, (bool, np.bool_)) and isinstance(value, (int, np.integer, float))
    if ok and isinstance(value, float):
        ok = np.isfinite(value) and value == int(value)
    if not ok or value < 0:
        raise SubmitError(
            f"the policy's metadata records steps {value!r}; valid: a whole number >= 0 "
            "(fix the policy's metadata; --steps declares the budget instead)"
        )


def load_spec(bench_dir: str | Path) -> Benchmark:
    """The benchmark's protocol (``DIR/benchmark.json``), or ``SubmitError`` naming the file."""
    path = benchfile.spec_path(bench_dir)
    try:
        exists = path.is_file()
    except OSError as err:  # a name the file system refuses (too long, ...)
        raise SubmitError(
            f"cannot use {bench_dir!s:.80} as a benchmark directory: {err.strerror}"
        ) from None
    if not exists:
        raise SubmitError(
            f"{bench_dir} is not a benchmark directory (no benchmark.json): create one with "
            f"`rrls benchmark --out {shlex.quote(str(bench_dir))} ...`, or pass --preset to "
            "`rrls submit` to start an empty one with that preset's protocol"
        )
    try:
        return benchfile.read_spec(bench_dir)
    except (SpecError, ValueError, OSError) as err:
        raise SubmitError(str(err)) from None


def preset_spec(preset: str, tasks: tuple[str, ...], **overrides: Any) -> Benchmark:
    """``preset``'s protocol on ``tasks`` without built-in algorithms (nothing written)."""
    from rrls.benchmark.grid import make_spec

    try:
        base = make_spec(preset, tasks=",".join(tasks), **overrides)
    except SpecError as err:
        raise SubmitError(str(err)) from None
    return replace(base, algos=())


def env_shapes(
    task: str, uncertainty: str, paper: bool = False
) -> tuple[tuple[int, ...], tuple[int, ...], int]:
    """The task's observation and action shapes (on the benchmark's physics: a task's physics
    may change them), and the set's dimension.

    One env is built: the task registry holds no shapes, which Gymnasium's MuJoCo envs derive
    from the compiled model and the env's keywords when they are made."""
    import gymnasium as gym

    from rrls.envs import resolve

    resolved = resolve(task, uncertainty)
    env = gym.make(f"rrls/robust-{resolved.task}-v0", **({"paper": True} if paper else {}))
    try:
        obs, act = env.observation_space.shape, env.action_space.shape
    finally:
        env.close()
    return tuple(obs), tuple(act), len(resolved.box.names)


def first_line(err: BaseException) -> str:
    """An exception as one line: its type and the first line of its message."""
    lines = str(err).strip().splitlines()
    return f"{type(err).__name__}: {lines[0]}" if lines else type(err).__name__


def load_policy(what: str, obj: Any) -> tuple[dict[str, Any], Any]:
    """``obj``'s source record and adapted policy; whatever loading raises (a module raising
    on import included) is a one-line ``SubmitError``."""
    from rrls.evaluation.policies import as_policy
    from rrls.evaluation.sources import policy_source

    prefix = "" if what == "policy" else f"--{what}: "
    try:
        return policy_source(obj), as_policy(obj)
    except (TypeError, ValueError, FileNotFoundError) as err:
        raise SubmitError(f"{prefix}{err}") from None
    except Exception as err:  # noqa: BLE001 - code of the submitter's: any failure, one line
        raise SubmitError(
            f"{prefix}cannot load the {what} {obj!s:.200} ({first_line(err)})"
        ) from None


def policy_identity(policy: Any, obs_dim: int, what: str = "policy") -> str:
    """What "the same policy" means: the same actions (on 64 probe observations of the size
    it sees: a TC-RMDP stacked/oracle protagonist's or adversary's input), whatever file or
    module holds it (a module whose weights file changed is another policy)."""
    from rrls.evaluation.prepared import policy_fingerprint

    try:
        return f"actions:{policy_fingerprint(policy, obs_dim, n=64)}"
    except Exception as err:  # noqa: BLE001 - the submitter's code
        raise SubmitError(f"the {what} fails on probe observations ({first_line(err)})") from None


def benchmark_for(root: Path, key: str, preset: str | None, add_task: bool) -> Benchmark:
    """The benchmark submitted to: the stored one, or ``preset``'s when none is stored yet;
    with ``key`` added if it may join (written only once the submission is in, by
    :func:`grown_benchmark`)."""
    if preset is not None and not benchfile.spec_path(root).exists():
        spec = preset_spec(preset, (key,))
    else:
        spec = load_spec(root)
    if key not in spec.tasks:
        check_new_task(root, spec, key, add_task)
        spec = replace(spec, tasks=(*spec.tasks, key))
    return spec


def grown_benchmark(root: Path, spec: Benchmark, key: str) -> Benchmark | None:
    """Under the lock: the benchmark to write with this submission — ``spec`` for a new one,
    the stored one (re-read now: another command may have added tasks or baselines meanwhile,
    nothing of theirs is lost) with ``key`` added, or None if it has ``key`` already."""
    if not benchfile.spec_path(root).exists():
        return spec
    stored = load_spec(root)
    if stored.binding_fields() != spec.binding_fields():
        raise SubmitError(
            f"{benchfile.spec_path(root)} changed during the evaluation (another protocol); "
            "nothing was submitted: submit again"
        )
    if key in stored.tasks:
        return None
    check_new_task(root, stored, key, add_task=True)  # submit() checked it may join
    return replace(stored, tasks=(*stored.tasks, key))


@dataclass(frozen=True)
class Entry:
    """What is submitted: the run it becomes (``algo``, ``task``, ``seed``), the policy, an
    adversary for the dynamic evaluation with its ``game`` and ``alpha``, and the training
    budget the submitter declares (``steps``, free-form ``budget``). See :func:`submit`."""

    algo: str
    task: str
    seed: int
    policy: Any
    adversary: Any = None
    game: str | None = None
    alpha: float | None = None
    steps: int | None = None
    budget: dict[str, str] | None = None


@dataclass(frozen=True)
class Checked:
    """An entry that passed every check, nothing run or changed yet: the benchmark (``spec``,
    the task added when it joins), the run's key and directory, the policy prepared for the
    protocol, the adversary, each with its source record and identity (its actions)."""

    root: Path
    spec: Benchmark
    algo: str
    task: str  # the registry's key
    seed: int
    final: Path  # the run directory it becomes
    policy: Any  # a PreparedPolicy
    source: dict[str, Any]
    identity: str
    steps: int | None
    budget: dict[str, str]
    adversary: Any = None
    adversary_source: dict[str, Any] | None = None
    adversary_identity: str | None = None
    game: str | None = None
    alpha: float | None = None

    @property
    def fingerprint(self) -> str:
        return self.policy.fingerprint


def check_submission(
    bench_dir: str | Path, entry: Entry, preset: str | None = None, add_task: bool = False
) -> Checked:
    """Everything about ``entry`` checked, before any episode runs or anything changes: its
    name, seed and declared budget, the benchmark (``preset``: started from it if
    ``bench_dir`` holds none; ``add_task``: the task may join), the game, then the policy and
    adversary loaded, their shapes and identities, the policy prepared for the protocol.
    Every refusal is one line, a ``SubmitError``."""
    from rrls.evaluation.prepared import prepare
    from rrls.evaluation.stack import policy_view
    from rrls.tasks import get_task

    check_name(entry.algo)
    seed = check_seed(entry.seed)
    steps = entry.steps
    if steps is not None and (isinstance(steps, bool) or not isinstance(steps, int) or steps < 1):
        raise SubmitError(f"--steps must be a whole number >= 1, got {steps!r}")
    try:
        key = get_task(entry.task).key
    except ValueError as err:
        raise SubmitError(str(err)) from None
    root = Path(bench_dir)
    spec = benchmark_for(root, key, preset, add_task)
    game, alpha = entry.game, entry.alpha
    if game is not None and game not in GAMES:
        raise SubmitError(f"unknown game {game!r}; valid: {', '.join(GAMES)}")
    if entry.adversary is None and (game is not None or alpha is not None):
        raise SubmitError("--game and --alpha need --adversary (the dynamic evaluation)")

    budget = check_budget(entry.budget)
    source, adapted = load_policy("policy", entry.policy)
    check_declared_steps(getattr(adapted, "metadata", None) or {})
    obs_shape, act_shape, set_dim = env_shapes(key, spec.uncertainty, is_paper(spec.physics))
    view = policy_view(adapted)  # an rrls TC-RMDP Stacked/Oracle protagonist: what it sees
    seen = obs_shape if view is None else (view.dim(obs_shape[0], act_shape[0]),)
    check_shapes(adapted, seen, act_shape, "policy", key)
    adversary: dict[str, Any] = {}
    if entry.adversary is not None:
        adversary = _checked_adversary(entry, spec, key, obs_shape, act_shape, set_dim)
    identity = policy_identity(adapted, seen[0])
    # prepared once, here: the mesh evaluation and the dynamic one take it as it is
    try:
        prepared = prepare(adapted, key, spec.protocol)
    except (OSError, MemoryError):
        raise
    except Exception as err:  # noqa: BLE001 - the submitter's code
        raise SubmitError(
            f"the evaluation failed ({first_line(err)}); nothing was submitted"
        ) from None
    final = root / "runs" / RunKey(entry.algo, key, seed).name(spec.uncertainty)
    return Checked(
        root=root,
        spec=spec,
        algo=entry.algo,
        task=key,
        seed=seed,
        final=final,
        policy=prepared,
        source=source,
        identity=identity,
        steps=steps,
        budget=budget,
        **adversary,
    )


def _checked_adversary(
    entry: Entry,
    spec: Benchmark,
    key: str,
    obs_shape: tuple[int, ...],
    act_shape: tuple[int, ...],
    set_dim: int,
) -> dict[str, Any]:
    """The adversary loaded and checked (its metadata against the game schema, its shapes in
    its game), its game and alpha (given, else what its file records): ``Checked``'s fields."""
    source, adv = load_policy("adversary", entry.adversary)
    try:  # what it says of its game: checked, one line (alpha: null is no alpha)
        meta = check_adversary(
            getattr(adv, "metadata", None), f"--adversary {entry.adversary!s:.80}", GAME_SCHEMA
        )
    except SchemaError as err:
        raise SubmitError(str(err)) from None
    game = entry.game or meta.get("game") or "adversarial"
    alpha = float(meta.get("alpha", 0.1)) if entry.alpha is None else entry.alpha
    adv_obs, adv_act = obs_shape, (set_dim,) if game == "adversarial" else act_shape
    if game == "adversarial" and spec.rate_limit is not None and spec.rate_game == "tc":
        # TC-RMDP: [ψ01, s], and the protagonist's action when omniscient (the default)
        omniscient = bool(meta.get("omniscient", True))
        adv_obs = (set_dim + obs_shape[0] + (act_shape[0] if omniscient else 0),)
    check_shapes(adv, adv_obs, adv_act, f"adversary ({game} game)", key)
    return {
        "adversary": adv,
        "adversary_source": source,
        "adversary_identity": policy_identity(adv, adv_obs[0], "adversary"),
        "game": game,
        "alpha": alpha,
    }
