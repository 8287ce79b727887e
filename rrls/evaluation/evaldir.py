"""The evaluation directory (``evaluate(..., out_dir=DIR)``), the one module that knows its
format, like ``rrls.rundir`` for runs::

    DIR/.lock               held while an evaluation writes (a second one is refused)
    DIR/evaluation.json     the arguments: a re-run resumes only with the same ones
    DIR/chunks/000003.npz   finished blocks of episodes (``rrls.evaluation.chunks``)
    DIR/summary.json        worst/average case, the protocol, versions (sealed)
    DIR/episodes.parquet    one row per (point, episode) (``.csv`` without pyarrow; sealed)
    DIR/dynamic.csv         a dynamic evaluation's episodes (``evaluate_dynamic``; sealed), also
                            what a benchmark's RARL / NR-MDP run holds
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from rrls.evaluation.chunks import CHUNK, saved
from rrls.files import (
    DirectoryLock,
    atomic_write_json,
    read_checked_json,
    read_checked_table,
    write_checked_json,
    write_checked_table,
)
from rrls.physics import ALIASES, physics_label
from rrls.schema import Schema, TableSchema, boolean, integer, number, obj, string
from rrls.seeds import MAX_SEED

__all__ = [
    "ARGUMENTS",
    "DYNAMIC",
    "SUMMARY",
    "kept",
    "write_dynamic",
    "opened",
    "read",
    "table_name",
    "write",
]

ARGUMENTS = "evaluation.json"
DYNAMIC = "dynamic.csv"
SUMMARY = "summary.json"
CHUNKS = "chunks"

#: ``summary.json``: the fields rrls reads are typed; the rest (the protocol's settings, the
#: policy's record) is open, as each protocol and policy adds its own
SUMMARY_SCHEMA = Schema(
    {
        "worst_case": number(required=True),
        "average_case": number(required=True),
        "points": integer(1, required=True),
        "episodes": integer(1),
        "episodes_total": integer(1),
        "mesh": integer(1),
        "seed": integer(0, MAX_SEED),
        "physics": string(choices=tuple(ALIASES)),
        "task": string(),
        "env": string(),
        "diverged": integer(0),
        "endpoint": boolean(null=True),
        "max_episode_steps": integer(1),
        "uncertainty": obj(Schema({}, open=True)),
        "worst_point": obj(Schema({}, open=True), null=True),
        "versions": obj(Schema({}, open=True)),
    },
    open=True,
)
#: the episode table's header (one row per episode; the set's parameters beside)
EPISODES_SCHEMA = TableSchema(
    {
        "point": "int",
        "episode": "int",
        "seed": "int",
        "return": "number",
        "length": "int",
        "terminated": "bool",
        "diverged": "bool",
    }
)

#: ``dynamic.csv``: one row per episode against the adversary (``terminated``/``diverged`` beside
#: in files written since dynamic evaluation runs on the engine)
DYNAMIC_SCHEMA = TableSchema({"episode": "int", "seed": "int", "return": "number", "length": "int"})


def table_name() -> str:
    """``episodes.parquet``, or ``episodes.csv`` where pyarrow is not installed."""
    try:
        import pyarrow  # noqa: F401
    except ImportError:
        return "episodes.csv"
    return "episodes.parquet"


@contextmanager
def opened(out_dir: str | Path, config: dict[str, Any]) -> Iterator[Path]:
    """Hold ``out_dir`` (one evaluation at a time) holding an evaluation with ``config``'s
    arguments, new or to resume; yields the folder of its chunks."""
    out_dir = Path(out_dir)
    with DirectoryLock(out_dir):
        path = out_dir / ARGUMENTS
        if path.exists():
            old = read_checked_json(path)
            if "physics" in old:  # older: rrls-v5 (paper-v4 refused)
                old["physics"] = physics_label(old["physics"])
            diff = sorted(k for k in set(old) | set(config) if old.get(k) != config.get(k))
            if diff:
                raise ValueError(
                    f"{out_dir} holds an evaluation with different arguments ({', '.join(diff)}); "
                    "use another output directory or the same arguments to resume"
                )
        else:
            atomic_write_json(path, config)
        yield out_dir / CHUNKS


def kept(out_dir: str | Path, episodes: int, finished: str = SUMMARY) -> str:
    """What an evaluation of ``episodes`` episode rows interrupted in ``out_dir`` keeps, in
    words (the line a command prints on Ctrl-C): its ``finished`` file (``summary.json``,
    ``dynamic.csv``) once written, else its saved chunks, which a re-run loads."""
    out_dir = Path(out_dir)
    if (out_dir / finished).exists():
        return f"the evaluation is complete in {out_dir} ({finished} written)"
    chunks, done = saved(out_dir / CHUNKS, episodes)
    return (
        f"{done:,} of {episodes:,} episodes ({chunks} of {-(-episodes // CHUNK)} chunks) kept "
        f"in {out_dir}"
    )


def write(out_dir: str | Path, summary: dict[str, Any], episodes: Any) -> Path:
    """Write the episode table and ``summary.json``, sealed (damage is seen on reading)."""
    out_dir = Path(out_dir)
    write_checked_table(out_dir / table_name(), episodes)
    write_checked_json(out_dir / SUMMARY, summary)
    return out_dir


def write_dynamic(out_dir: str | Path, episodes: Any) -> Path:
    """Write a dynamic evaluation's episode table, sealed."""
    path = Path(out_dir) / DYNAMIC
    write_checked_table(path, episodes)
    return path


def read(out_dir: str | Path) -> tuple[dict[str, Any], Any]:
    """``(summary, episodes)`` of a finished evaluation; one-line errors naming what is
    missing or damaged."""
    out_dir = Path(out_dir)
    summary_path = out_dir / SUMMARY
    if not summary_path.exists():
        raise FileNotFoundError(f"{out_dir} holds no summary.json: not an rrls evaluation")
    summary = SUMMARY_SCHEMA.check(read_checked_json(summary_path), str(summary_path))
    table = out_dir / "episodes.parquet"
    if not table.exists():
        table = out_dir / "episodes.csv"
    try:
        episodes = read_checked_table(table)  # a damaged table: one line naming it
    except FileNotFoundError:
        raise FileNotFoundError(f"{out_dir} holds no episodes table") from None
    return summary, EPISODES_SCHEMA.check(episodes, str(table))
