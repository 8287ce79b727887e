"""``rrls submit``: put a policy trained anywhere through a benchmark's protocol, as a run.

A submitted policy is evaluated exactly as the benchmark's own runs are (the same set, mesh,
episodes and episode seeds; with an adversary also the dynamic evaluation) and written as a run
directory ``DIR/runs/<name>-<task>-<set>-seed<S>/`` in the layout the result store reads
(``eval/``, ``dynamic.csv``, ``result.json`` last). ``rrls report DIR`` then shows the algorithm
in every table and figure like a baseline. ``result.json`` records where the policy came from
(``submitted``: kind, source, SHA-256 of the file, and its identity: the fingerprint of its
actions), so a report can say which rows were trained here and which were brought.

Nothing of the benchmark's spec changes: ``rrls benchmark`` over the same directory neither
trains nor touches a submitted algorithm, and rebuilding the store keeps it.

>>> from rrls.experiments.submission import check_name
>>> check_name("my-sac")
'my-sac'
>>> for name in ("TD3", "SAC-DR"):
...     try:
...         check_name(name)
...     except ValueError as err:
...         print(str(err).split(" (")[0])
--algo 'TD3' is a built-in algorithm
--algo 'SAC-DR' is a built-in algorithm
"""

from __future__ import annotations

import os
import re
import shlex
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from rrls._io import json_bytes
from rrls.algorithms import ALGORITHMS, plugin_entry_points
from rrls.evaluation.dynamic import GAME_SCHEMA, GAMES, check_adversary
from rrls.experiments.changes import Changes
from rrls.experiments.spec import BUILT_IN, RunKey, Spec, SpecError
from rrls.experiments.stages import run_dynamic, run_evaluation
from rrls.experiments.store import write_result
from rrls.experiments.submitted import discard, jsonable
from rrls.physics import is_paper
from rrls.schema import SchemaError

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


@dataclass(frozen=True)
class Submission:
    """What ``submit`` did: the run directory, its ``result.json`` and whether it evaluated."""

    run_dir: Path
    result: dict[str, Any]
    evaluated: bool  # False: the same policy was already submitted (nothing to do)

    @property
    def worst_case(self) -> float:
        return float(self.result["worst_case"])

    @property
    def average_case(self) -> float:
        return float(self.result["average_case"])


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


def load_spec(bench_dir: str | Path) -> Spec:
    """The benchmark's protocol (``DIR/benchmark.json``), or ``SubmitError`` naming the file."""
    from rrls.experiments import benchfile

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


def _preset_spec(preset: str, tasks: tuple[str, ...], **overrides: Any) -> Spec:
    """``preset``'s protocol on ``tasks`` without built-in algorithms (nothing written)."""
    from dataclasses import replace

    from rrls.experiments.spec import make_spec

    try:
        base = make_spec(preset, tasks=",".join(tasks), **overrides)
    except SpecError as err:
        raise SubmitError(str(err)) from None
    return replace(base, algos=())


def create_benchmark(
    bench_dir: str | Path, preset: str, tasks: tuple[str, ...], **overrides: Any
) -> Spec:
    """An empty benchmark (no built-in algorithm to train) with ``preset``'s protocol on
    ``tasks`` (``overrides``: ``make_spec``'s options, e.g. ``mesh``, ``episodes``):
    submissions compare against a reference file (``rrls report --reference``), and
    ``rrls benchmark --out DIR --preset P`` (same options) may later add the baselines to it.
    A directory already holding a benchmark is refused."""
    from rrls.experiments import benchfile

    if benchfile.spec_path(bench_dir).exists():
        raise SubmitError(f"{bench_dir} already holds a benchmark (benchmark.json)")
    spec = _preset_spec(preset, tasks, **overrides)
    Path(bench_dir).mkdir(parents=True, exist_ok=True)
    with benchfile.locked(bench_dir):
        if benchfile.spec_path(bench_dir).exists():  # created meanwhile by another command
            raise SubmitError(f"{bench_dir} already holds a benchmark (benchmark.json)")
        benchfile.write_spec(bench_dir, spec)
    return spec


def _env_shapes(
    task: str, uncertainty: str, paper: bool = False
) -> tuple[tuple[int, ...], tuple[int, ...], int]:
    """The task's observation and action shapes (on the benchmark's physics: a task's physics
    may change them), and the set's dimension (one env built)."""
    import gymnasium as gym

    from rrls.envs import resolve

    resolved = resolve(task, uncertainty)
    env = gym.make(f"rrls/robust-{resolved.task}-v0", **({"paper": True} if paper else {}))
    try:
        obs, act = env.observation_space.shape, env.action_space.shape
    finally:
        env.close()
    return tuple(obs), tuple(act), len(resolved.box.names)


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


def _first_line(err: BaseException) -> str:
    lines = str(err).strip().splitlines()
    return f"{type(err).__name__}: {lines[0]}" if lines else type(err).__name__


def _load(what: str, obj: Any) -> tuple[dict[str, Any], Any]:
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
            f"{prefix}cannot load the {what} {obj!s:.200} ({_first_line(err)})"
        ) from None


def _identity(policy: Any, obs_dim: int, what: str = "policy") -> str:
    """What "the same policy" means: the same actions (on 64 probe observations of the size
    it sees: a TC-RMDP stacked/oracle protagonist's or adversary's input), whatever file or
    module holds it (a module whose weights file changed is another policy)."""
    from rrls.evaluation.policies import policy_fingerprint

    try:
        return f"actions:{policy_fingerprint(policy, obs_dim, n=64)}"
    except Exception as err:  # noqa: BLE001 - the submitter's code
        raise SubmitError(f"the {what} fails on probe observations ({_first_line(err)})") from None


def _same(
    record: dict[str, Any], identity: str, fingerprint: str, adv_identity: str | None
) -> bool:
    """Whether a stored submission is this one (older records: by their action fingerprint)."""
    mine = record.get("identity") == identity or (
        str(record.get("identity", "")).startswith("sha256:")
        and record.get("fingerprint") == fingerprint
    )
    return mine and (record.get("adversary") or {}).get("identity") == adv_identity


def _existing(
    final: Path, identity: str, fingerprint: str, adv_identity: str | None, overwrite: bool
) -> Submission | None:
    """The stored submission if it is this one; ``SubmitError`` if it must not be replaced."""
    from rrls import rundir

    if not (final / rundir.RESULT).exists():
        return None
    try:
        old = rundir.read_checked_json(final / rundir.RESULT)
    except ValueError as err:
        raise SubmitError(str(err)) from None
    record = old.get("submitted")
    if record is None:
        raise SubmitError(f"{final} is a trained run, not a submission; it is never replaced")
    if _same(record, identity, fingerprint, adv_identity):  # the same policy: nothing to do
        return Submission(final, old, evaluated=False)
    if not overwrite:
        raise SubmitError(
            f"{old.get('algorithm')}/{old.get('task')}/seed {old.get('seed')} was already "
            f"submitted with another policy ({record.get('source')}); pass --overwrite to "
            "replace it"
        )
    return None


def submit(
    bench_dir: str | Path,
    algo: str,
    task: str,
    seed: int,
    policy: Any,
    adversary: Any = None,
    overwrite: bool = False,
    *,
    game: str | None = None,
    alpha: float | None = None,
    preset: str | None = None,
    workers: int | None = None,
    progress: bool | None = None,
    add_task: bool = False,
    steps: int | None = None,
    budget: dict[str, str] | None = None,
) -> Submission:
    """Evaluate ``policy`` under ``bench_dir``'s protocol and store it as run ``(algo, task,
    seed)``; ``rrls report bench_dir`` then shows ``algo`` beside the baselines.

    ``policy``: a callable ``obs[B, d] -> act[B, k]``, a torch ``nn.Module``, a
    Stable-Baselines3 model, or a path: an rrls ``.npz``, an ``rrls train`` run directory, an
    SB3 ``.zip``, or ``module:attribute``. **An SB3 zip or ``module:attribute`` runs code** (SB3
    unpickles its classes; importing runs the module): submit only what you trust.
    ``adversary`` (same kinds): also play the dynamic evaluation (paper Table 6) — ``game``
    ``adversarial`` (the adversary picks the benchmark set's parameters every step, actions in
    ``[-1, 1]^dim``), ``nr`` or ``pr`` (action-robust, ``alpha``, default 0.1); by default the
    game an rrls adversary file records, else ``adversarial``.
    The same (algo, task, seed) again with the same policy (the same actions) does nothing;
    with another policy it is refused unless ``overwrite``. ``preset``: if ``bench_dir`` holds
    no benchmark yet, start an empty one with that preset's protocol on ``task``. A task the
    benchmark does not have is refused unless ``add_task`` (a submissions-only benchmark then
    grows it; one with baselines never does: their runs would be missing). ``steps``: the
    training budget the submitter declares (else what the policy's metadata records; neither:
    not stated); ``budget``: anything else about it (``{"env steps": "1e6", ...}``); both go
    into the run's files and the report prints each source's budget beside the benchmark's.

    A refused or failed submission changes nothing: everything is checked (the policy, its
    metadata, the budget, the result's fields) before the first change, and the changes (the
    run directory, an earlier submission replaced, the task list grown) are made together
    under the benchmark's lock, undone if any of them fails (``rrls.experiments.changes``).
    """
    from dataclasses import replace

    from rrls.evaluation.prepared import prepare
    from rrls.evaluation.stack import policy_view
    from rrls.experiments import benchfile
    from rrls.tasks import get_task

    check_name(algo)
    seed = check_seed(seed)
    if steps is not None and (isinstance(steps, bool) or not isinstance(steps, int) or steps < 1):
        raise SubmitError(f"--steps must be a whole number >= 1, got {steps!r}")
    try:
        key = get_task(task).key
    except ValueError as err:
        raise SubmitError(str(err)) from None
    root = Path(bench_dir)
    if preset is not None and not benchfile.spec_path(root).exists():
        spec = _preset_spec(preset, (key,))
    else:
        spec = load_spec(root)
    if key not in spec.tasks:
        _check_new_task(root, spec, key, add_task)
        spec = replace(spec, tasks=(*spec.tasks, key))  # written once the submission is in
    if game is not None and game not in GAMES:
        raise SubmitError(f"unknown game {game!r}; valid: {', '.join(GAMES)}")
    if adversary is None and (game is not None or alpha is not None):
        raise SubmitError("--game and --alpha need --adversary (the dynamic evaluation)")

    budget = _check_budget(budget)
    source, adapted = _load("policy", policy)
    _check_declared_steps(getattr(adapted, "metadata", None) or {})
    obs_shape, act_shape, set_dim = _env_shapes(key, spec.uncertainty, is_paper(spec.physics))
    view = policy_view(adapted)  # an rrls TC-RMDP Stacked/Oracle protagonist: what it sees
    seen = obs_shape if view is None else (view.dim(obs_shape[0], act_shape[0]),)
    check_shapes(adapted, seen, act_shape, "policy", key)
    adv = adv_source = adv_identity = None
    adv_obs = obs_shape
    if adversary is not None:
        adv_source, adv = _load("adversary", adversary)
        try:  # what it says of its game: checked, one line (alpha: null is no alpha)
            meta = check_adversary(
                getattr(adv, "metadata", None), f"--adversary {adversary!s:.80}", GAME_SCHEMA
            )
        except SchemaError as err:
            raise SubmitError(str(err)) from None
        game = game or meta.get("game") or "adversarial"
        if alpha is None:
            alpha = float(meta.get("alpha", 0.1))
        adv_act = (set_dim,) if game == "adversarial" else act_shape
        if game == "adversarial" and spec.rate_limit is not None and spec.rate_game == "tc":
            # TC-RMDP: [ψ01, s], and the protagonist's action when omniscient (the default)
            omniscient = bool(meta.get("omniscient", True))
            adv_obs = (set_dim + obs_shape[0] + (act_shape[0] if omniscient else 0),)
        check_shapes(adv, adv_obs, adv_act, f"adversary ({game} game)", key)
        adv_identity = _identity(adv, adv_obs[0], "adversary")
    identity = _identity(adapted, seen[0])
    # prepared once, here: the mesh evaluation and the dynamic one take it as it is
    try:
        adapted = prepare(adapted, key, spec.protocol)
    except (OSError, MemoryError):
        raise
    except Exception as err:  # noqa: BLE001 - the submitter's code
        raise SubmitError(
            f"the evaluation failed ({_first_line(err)}); nothing was submitted"
        ) from None
    fingerprint = adapted.fingerprint

    final = root / "runs" / RunKey(algo, key, seed).name(spec.uncertainty)
    done = _existing(final, identity, fingerprint, adv_identity, overwrite)
    if done is not None:
        return done

    staging = root / "submissions" / ".staging" / f"{final.name}-{os.getpid()}-{time.time_ns()}"
    made = [p for p in (root, root / "submissions", staging.parent) if not p.exists()]
    try:
        staging.mkdir(parents=True)
        result = run_evaluation(spec, algo, key, seed, adapted, staging, workers, progress)
        declared = "submitter" if steps is not None else "policy" if result["steps"] else None
        if steps is not None:
            result["steps"] = int(steps)
        if adv is not None:
            game = game or "adversarial"
            result.update(run_dynamic(spec, key, adapted, adv, game, alpha, staging))
    except (OSError, MemoryError):  # the disk or memory: said as every command says it
        discard(staging, made)
        raise
    except Exception as err:  # noqa: BLE001 - the submitter's code raised mid-evaluation
        discard(staging, made)
        raise SubmitError(
            f"the evaluation failed ({_first_line(err)}); nothing was submitted"
        ) from None
    result["submitted"] = {
        **source,
        "identity": identity,
        "fingerprint": fingerprint,
        "metadata": jsonable(getattr(adapted, "metadata", None) or {}),
        "submitted_at": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
        "budget": {
            "steps": result["steps"] or None,
            "declared_by": declared,  # submitter, the policy's metadata, or None: not stated
            **budget,
        },
        "adversary": None
        if adv is None
        else {
            **(adv_source or {}),
            "identity": adv_identity,
            "game": game,
            "alpha": alpha if game != "adversarial" else None,
        },
    }
    try:
        write_result(staging, result)  # checked against the result schema before any change
        with benchfile.locked(root):  # concurrent submissions: one at a time from here
            done = _existing(final, identity, fingerprint, adv_identity, overwrite)
            if done is not None:  # the same policy, submitted meanwhile
                discard(staging, made)
                return done
            grown = _grown_spec(root, spec, key)
            with Changes(root) as change:  # all or nothing: undone if any step fails
                if final.exists():
                    change.remove(final)  # the earlier submission (--overwrite)
                change.move(staging, final)
                if grown is not None:
                    change.write(benchfile.spec_path(root), json_bytes(grown.to_json()))
    except BaseException as err:
        discard(staging, made)
        if isinstance(err, SchemaError):
            raise SubmitError(f"{err}; nothing was submitted") from None
        raise
    discard(staging, made)  # the staging folders it created, now empty
    return Submission(final, result, evaluated=True)


def _check_new_task(root: Path, spec: Spec, key: str, add_task: bool) -> None:
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


def _check_budget(budget: dict[str, Any] | None) -> dict[str, str]:
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


def _check_declared_steps(meta: dict[str, Any]) -> None:
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


def _grown_spec(root: Path, spec: Spec, key: str) -> Spec | None:
    """Under the lock: the benchmark to write with this submission — ``spec`` for a new one,
    the stored one (re-read now: another command may have added tasks or baselines meanwhile,
    nothing of theirs is lost) with ``key`` added, or None if it has ``key`` already."""
    from dataclasses import replace

    from rrls.experiments import benchfile

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
    _check_new_task(root, stored, key, add_task=True)  # submit() checked it may join
    return replace(stored, tasks=(*stored.tasks, key))
