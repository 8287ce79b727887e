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

>>> from rrls.submissions.steps import check_name
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

import json
import os
import shutil
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from rrls.benchmark.changes import Changes
from rrls.benchmark.grid import Benchmark
from rrls.benchmark.stages import run_dynamic, run_evaluation
from rrls.benchmark.store import write_result
from rrls.files import json_bytes
from rrls.schema import SchemaError
from rrls.submissions.checks import (
    RESERVED,
    Checked,
    Entry,
    SubmitError,
    check_name,
    check_seed,
    check_shapes,
    check_submission,
    first_line,
    grown_benchmark,
    load_spec,
    preset_spec,
    reserved_names,
)

__all__ = [  # the checks live in rrls.submissions.checks; importable from here too
    "RESERVED",
    "Checked",
    "Entry",
    "Staged",
    "Submission",
    "SubmitError",
    "check_name",
    "check_seed",
    "check_shapes",
    "check_submission",
    "create_benchmark",
    "evaluate_submission",
    "install_submission",
    "load_spec",
    "reserved_names",
    "submit",
]


@dataclass(frozen=True)
class Staged:
    """An evaluated entry: its run directory in a staging folder (``made``: the folders created
    for it, removed with it) and the ``result.json`` fields to install."""

    dir: Path
    made: list[Path]
    result: dict[str, Any] = field(default_factory=dict)


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


def create_benchmark(
    bench_dir: str | Path, preset: str, tasks: tuple[str, ...], **overrides: Any
) -> Benchmark:
    """An empty benchmark (no built-in algorithm to train) with ``preset``'s protocol on
    ``tasks`` (``overrides``: ``make_spec``'s options, e.g. ``mesh``, ``episodes``):
    submissions compare against a reference file (``rrls report --reference``), and
    ``rrls benchmark --out DIR --preset P`` (same options) may later add the baselines to it.
    A directory already holding a benchmark is refused."""
    from rrls.benchmark import benchfile

    if benchfile.spec_path(bench_dir).exists():
        raise SubmitError(f"{bench_dir} already holds a benchmark (benchmark.json)")
    spec = preset_spec(preset, tasks, **overrides)
    Path(bench_dir).mkdir(parents=True, exist_ok=True)
    with benchfile.locked(bench_dir):
        if benchfile.spec_path(bench_dir).exists():  # created meanwhile by another command
            raise SubmitError(f"{bench_dir} already holds a benchmark (benchmark.json)")
        benchfile.write_spec(bench_dir, spec)
    return spec


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
    under the benchmark's lock, undone if any of them fails (``rrls.benchmark.changes``).
    The three steps: :func:`check_submission`, :func:`evaluate_submission`,
    :func:`install_submission`.
    """
    entry = Entry(algo, task, seed, policy, adversary, game, alpha, steps, budget)
    checked = check_submission(bench_dir, entry, preset=preset, add_task=add_task)
    done = _existing(checked, overwrite)
    if done is not None:  # the same policy, submitted before: nothing to do
        return done
    staged = evaluate_submission(checked, workers=workers, progress=progress)
    return install_submission(checked, staged, overwrite)


def evaluate_submission(
    checked: Checked, workers: int | None = None, progress: bool | None = None
) -> Staged:
    """The mesh evaluation (and with an adversary the dynamic one) of a checked entry, into a
    staging folder of this process under ``submissions/``: its run directory and
    ``result.json`` fields, where it came from and its budget included. A failure removes the
    folder (the submitter's code raising: a one-line ``SubmitError``)."""
    root, spec, key = checked.root, checked.spec, checked.task
    name = f"{checked.final.name}-{os.getpid()}-{time.time_ns()}"
    staging = root / "submissions" / ".staging" / name
    made = [p for p in (root, root / "submissions", staging.parent) if not p.exists()]
    try:
        staging.mkdir(parents=True)
        policy = checked.policy
        result = run_evaluation(
            spec, checked.algo, key, checked.seed, policy, staging, workers, progress
        )
        steps = checked.steps
        declared = "submitter" if steps is not None else "policy" if result["steps"] else None
        if steps is not None:
            result["steps"] = int(steps)
        if checked.adversary is not None:
            game = checked.game or "adversarial"
            adversary, alpha = checked.adversary, checked.alpha
            result.update(run_dynamic(spec, key, policy, adversary, game, alpha, staging))
    except (OSError, MemoryError, KeyboardInterrupt):  # the disk, memory, Ctrl-C: as said
        discard(staging, made)  # everywhere; a re-run evaluates afresh (staging is per process)
        raise
    except Exception as err:  # noqa: BLE001 - the submitter's code raised mid-evaluation
        discard(staging, made)
        raise SubmitError(
            f"the evaluation failed ({first_line(err)}); nothing was submitted"
        ) from None
    result["submitted"] = _record(checked, result["steps"], declared)
    return Staged(staging, made, result)


def discard(staging: Path, made: list[Path]) -> None:
    """Remove a submission's staging directory and the directories it created."""
    shutil.rmtree(staging, ignore_errors=True)
    for path in reversed(made):
        try:
            path.rmdir()  # only if empty: another command's files stay
        except OSError:
            pass


def jsonable(meta: dict[str, Any]) -> dict[str, Any]:
    """A policy's metadata as JSON holds it (anything else as its text)."""
    return json.loads(json.dumps(meta, default=str))


def _record(checked: Checked, steps: int, declared: str | None) -> dict[str, Any]:
    """``result.json``'s ``submitted``: the source, identity and metadata of the policy, when,
    the budget and who declared it, the adversary and its game."""
    game = checked.game
    return {
        **checked.source,
        "identity": checked.identity,
        "fingerprint": checked.fingerprint,
        "metadata": jsonable(getattr(checked.policy, "metadata", None) or {}),
        "submitted_at": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
        "budget": {
            "steps": steps or None,
            "declared_by": declared,  # submitter, the policy's metadata, or None: not stated
            **checked.budget,
        },
        "adversary": None
        if checked.adversary is None
        else {
            **(checked.adversary_source or {}),
            "identity": checked.adversary_identity,
            "game": game,
            "alpha": checked.alpha if game != "adversarial" else None,
        },
    }


def install_submission(checked: Checked, staged: Staged, overwrite: bool = False) -> Submission:
    """The evaluated run installed, all or nothing under the benchmark's lock: its
    ``result.json`` checked against the schema, an earlier submission replaced (``overwrite``),
    the run moved in, the task list grown when the task joins; undone if any step fails
    (``rrls.benchmark.changes``), the staging folders removed whatever happens."""
    from rrls.benchmark import benchfile

    root, final = checked.root, checked.final
    try:
        write_result(staged.dir, staged.result)  # checked against the schema before a change
        with benchfile.locked(root):  # concurrent submissions: one at a time from here
            done = _existing(checked, overwrite)
            if done is not None:  # the same policy, submitted meanwhile
                discard(staged.dir, staged.made)
                return done
            grown = grown_benchmark(root, checked.spec, checked.task)
            with Changes(root) as change:  # all or nothing: undone if any step fails
                if final.exists():
                    change.remove(final)  # the earlier submission (--overwrite)
                change.move(staged.dir, final)
                if grown is not None:
                    change.write(benchfile.spec_path(root), json_bytes(grown.to_json()))
    except BaseException as err:
        discard(staged.dir, staged.made)
        if isinstance(err, SchemaError):
            raise SubmitError(f"{err}; nothing was submitted") from None
        raise
    discard(staged.dir, staged.made)  # the staging folders it created, now empty
    return Submission(final, staged.result, evaluated=True)


def _same(record: dict[str, Any], checked: Checked) -> bool:
    """Whether a stored submission is this one (older records: by their action fingerprint)."""
    mine = record.get("identity") == checked.identity or (
        str(record.get("identity", "")).startswith("sha256:")
        and record.get("fingerprint") == checked.fingerprint
    )
    adversary = (record.get("adversary") or {}).get("identity")
    return mine and adversary == checked.adversary_identity


def _existing(checked: Checked, overwrite: bool) -> Submission | None:
    """The stored submission if it is this one; ``SubmitError`` if it must not be replaced."""
    from rrls import files, rundir

    final = checked.final
    if not (final / rundir.RESULT).exists():
        return None
    try:
        old = files.read_checked_json(final / rundir.RESULT)
    except ValueError as err:
        raise SubmitError(str(err)) from None
    record = old.get("submitted")
    if record is None:
        raise SubmitError(f"{final} is a trained run, not a submission; it is never replaced")
    if _same(record, checked):  # the same policy: nothing to do
        return Submission(final, old, evaluated=False)
    if not overwrite:
        raise SubmitError(
            f"{old.get('algorithm')}/{old.get('task')}/seed {old.get('seed')} was already "
            f"submitted with another policy ({record.get('source')}); pass --overwrite to "
            "replace it"
        )
    return None
