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
import shlex
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from rrls._io import json_bytes
from rrls.evaluation.dynamic import GAME_SCHEMA, GAMES, check_adversary
from rrls.experiments.changes import Changes
from rrls.experiments.spec import RunKey, Spec, SpecError
from rrls.experiments.stages import run_dynamic, run_evaluation
from rrls.experiments.store import write_result
from rrls.experiments.submit_checks import (
    RESERVED,
    SubmitError,
    check_budget,
    check_declared_steps,
    check_name,
    check_new_task,
    check_seed,
    check_shapes,
    reserved_names,
)
from rrls.experiments.submitted import discard, jsonable
from rrls.physics import is_paper
from rrls.schema import SchemaError

__all__ = [  # the checks live in rrls.experiments.submit_checks; importable from here too
    "RESERVED",
    "Submission",
    "SubmitError",
    "check_name",
    "check_seed",
    "check_shapes",
    "create_benchmark",
    "load_spec",
    "reserved_names",
    "submit",
]


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
        check_new_task(root, spec, key, add_task)
        spec = replace(spec, tasks=(*spec.tasks, key))  # written once the submission is in
    if game is not None and game not in GAMES:
        raise SubmitError(f"unknown game {game!r}; valid: {', '.join(GAMES)}")
    if adversary is None and (game is not None or alpha is not None):
        raise SubmitError("--game and --alpha need --adversary (the dynamic evaluation)")

    budget = check_budget(budget)
    source, adapted = _load("policy", policy)
    check_declared_steps(getattr(adapted, "metadata", None) or {})
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
    except (OSError, MemoryError, KeyboardInterrupt):  # the disk, memory, Ctrl-C: as said
        discard(staging, made)  # everywhere; a re-run evaluates afresh (staging is per process)
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
    check_new_task(root, stored, key, add_task=True)  # submit() checked it may join
    return replace(stored, tasks=(*stored.tasks, key))
