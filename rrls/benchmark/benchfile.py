"""``DIR/benchmark.json``, the benchmark's protocol: sealed like every results file (a damaged
one is a one-line error naming it, never a report of wrong numbers) and changed only under a
lock, so that commands adding tasks or runs at the same time (``rrls benchmark``, concurrent
``rrls submit``) lose no update."""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import replace
from pathlib import Path
from typing import Any

from rrls import files
from rrls.benchmark.grid import Benchmark, SpecError
from rrls.evaluation.protocol import MAX_EPISODES
from rrls.files import waiting_lock
from rrls.physics import ALIASES, SIMULATORS
from rrls.schema import Schema, SchemaError, array, boolean, integer, number, obj, string
from rrls.seeds import MAX_SEED, MAX_SEEDS
from rrls.uncertainty import MAX_MESH_POINTS
from rrls.wrappers.tc_rmdp import OBSERVE, RATE_GAMES

NAME = "benchmark.json"
#: the lock file beside it (an ``flock``: a killed holder releases it)
LOCK = ".benchmark.lock"

_STEPS = integer(1, 10**12)
#: the template run's fields, as every format stores them
_TRAINING = {
    "algos": array(string(), max_items=1_000),
    "tasks": array(string(), max_items=1_000),
    "seeds": array(integer(0, MAX_SEED), max_items=MAX_SEEDS),
    "steps": _STEPS,
    "learning_starts": integer(0, 10**12, null=True),
    "eval_every": integer(0, 10**12),
    "eval_episodes": integer(1, MAX_EPISODES),
    "eval_mesh": integer(0, MAX_MESH_POINTS),
    "learning_rate": number(0, low_open=True, null=True),
    "normalize_omega": boolean(),
    "hidden": array(integer(1, 1_000_000), max_items=64),
    "batch_size": integer(1, 10**8, null=True),
    "checkpoint_every": _STEPS,
    "preset": string(),
    "device": string(),
    "observe": string(choices=OBSERVE),
    "simulator": string(choices=SIMULATORS),
}
#: ``benchmark.json``: ``Benchmark``'s fields, the protocol as ``Protocol.to_json`` writes it (which
#: ``Protocol.from_json`` checks field by field); every other field optional (a field added
#: after a file was written takes its default)
SPEC_SCHEMA = Schema({**_TRAINING, "protocol": obj()})
#: a ``benchmark.json`` written before it held the protocol whole: the protocol's fields flat
#: beside the template run's (``eval_seed``: the protocol's seed); read as the same benchmark
FLAT_SCHEMA = Schema(
    {
        **_TRAINING,
        "uncertainty": string(),
        "mesh": integer(1, MAX_MESH_POINTS),
        "endpoint": boolean(null=True),
        "episodes": integer(1, MAX_EPISODES),
        "dynamic_episodes": integer(1, MAX_EPISODES),
        "eval_seed": integer(0, MAX_SEED),
        "physics": string(choices=tuple(ALIASES)),
        "rate_limit": number(0, low_open=True, null=True),
        "rate_game": string(choices=RATE_GAMES),
        "split": string(null=True),
        "recheck": obj(null=True),
    }
)


def spec_path(root: str | Path) -> Path:
    return Path(root) / NAME


def read_stored_json(root: str | Path) -> dict[str, Any]:
    """The file as it is stored (``FileNotFoundError`` if there is none, ``DamagedFile`` if its
    bytes are not those written)."""
    return files.read_checked_json(spec_path(root))


def read_spec(root: str | Path) -> Benchmark:
    """The stored ``Benchmark`` (a file of any earlier format migrated); a file that is not one is
    a ``SpecError`` naming it."""
    data = read_stored_json(root)
    schema = SPEC_SCHEMA if isinstance(data, dict) and "protocol" in data else FLAT_SCHEMA
    try:
        schema.check(data, str(spec_path(root)))
    except SchemaError as err:
        raise SpecError(str(err)) from None
    try:
        return Benchmark.from_json(data)
    except (ValueError, TypeError, KeyError, AttributeError) as err:
        raise SpecError(f"{spec_path(root)} is not a benchmark spec ({err})") from None


def read_spec_json(root: str | Path) -> dict[str, Any]:
    """The stored benchmark as its readers take it (the report, reference files): its fields
    flat, whatever the format it was written in (``Benchmark.flat_json``)."""
    return read_spec(root).flat_json()


def stored_fingerprints(root: str | Path) -> dict[str, str]:
    """The stored benchmark's fingerprints (``Benchmark.fingerprints``), none without a spec."""
    return read_spec(root).fingerprints() if spec_path(root).exists() else {}


def write_spec(root: str | Path, spec: Benchmark) -> Path:
    """Write (and seal) ``spec`` as the directory's protocol; hold :func:`locked` around the
    read that it updates."""
    return files.write_checked_json(spec_path(root), spec.to_json())


@contextmanager
def locked(root: str | Path) -> Iterator[None]:
    """Hold the benchmark's lock (waiting for another command to release it)."""
    with waiting_lock(Path(root) / LOCK):
        yield


#: the lock of the store and the report (``results/``, ``report/``): rebuilt by ``rrls
#: benchmark`` at its end and by ``rrls report``, one command at a time
REPORT_LOCK = ".report.lock"


@contextmanager
def reporting(root: str | Path) -> Iterator[None]:
    """Hold the store's and report's lock (waiting for another report to finish)."""
    with waiting_lock(Path(root) / REPORT_LOCK):
        yield


def reconcile(out: Path, spec: Benchmark) -> Benchmark:
    """The spec to store in ``out``: ``spec`` itself, or the union with the stored one.

    Refuses (``SpecError``) a directory whose stored protocol differs, naming the fields.
    """
    if not spec_path(out).exists():
        return spec
    stored = read_spec(out)  # damaged / not a spec: one line naming the file
    old, new = stored.binding_fields(), spec.binding_fields()
    diff = [k for k in sorted(set(old) | set(new)) if old.get(k) != new.get(k)]
    if diff:
        detail = "; ".join(f"{k}: {old.get(k)!r} there, {new.get(k)!r} now" for k in diff)
        raise SpecError(
            f"{out} holds a benchmark with another protocol ({detail}); use another --out or "
            "the same options (adding algorithms, tasks or seeds is allowed)"
        )
    return replace(
        stored,
        algos=tuple(dict.fromkeys(stored.algos + spec.algos)),
        tasks=tuple(dict.fromkeys(stored.tasks + spec.tasks)),
        seeds=tuple(sorted(set(stored.seeds) | set(spec.seeds))),
        device=spec.device,
        recheck=spec.recheck or stored.recheck,
    )
