"""Reference results as data: the one module that knows the reference file format.

A reference is what a lab (or the paper) measured under one evaluation protocol: per task, set
and algorithm, the worst-case and average-case (and dynamic) mean over seeds, with the std, the
number of seeds and, when known, the per-seed values (with the seeds they belong to, in seed
order). ``rrls report DIR --reference FILE``
normalises a task with the reference's TD3 and M2TD3 when the benchmark has not trained its own,
and ``rrls report DIR --export-reference FILE`` writes a benchmark's results as such a file
(``rrls.report.exported``).

A reference is only a reference for a benchmark that measures the same thing: the same
``physics``, uncertainty set, mesh (points per dimension, endpoint) and episodes per point;
anything else is refused (``ReferenceError``, one line naming the fields). So is a reference
trained with another budget (``steps``, or none stated) unless the report is asked for it
(``rrls report --allow-other-budget``): its rows are then marked ‡ and normalised by its own
TD3 and M2TD3, not set beside the benchmark's as like-for-like.

JSON (``.json``)::

    {"format": "rrls-reference", "version": 1, "label": "...", "physics": "v5",
     "mesh": 10, "episodes": 5, "endpoint": true, "steps": 20000, "eval_seed": 0,
     "versions": {"rrls": "...", "gymnasium": "...", "mujoco": "..."}, "notes": "...",
     "rows": [{"task": "hopper", "uncertainty": "3d", "algorithm": "td3",
               "metric": "worst_case", "mean": 69.3, "std": 42.77, "n_seeds": 10,
               "values": [...] or null, "seeds": [...] (optional)}, ...]}

CSV (any other suffix): one line per row with the same columns, the metadata repeated on every
line (``label, physics, mesh, episodes, endpoint, steps, eval_seed, rrls_version,
gymnasium_version, mujoco_version``) and ``values`` (and ``seeds``) as ``;``-separated numbers
(or empty).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

from rrls.evaluation.protocol import MAX_EPISODES
from rrls.files import loads_json, read_json
from rrls.physics import ALIASES, PAPER, V5, physics_label
from rrls.schema import JsonError, Schema, SchemaError, array, boolean, integer, number, obj, string
from rrls.seeds import MAX_SEED, MAX_SEEDS
from rrls.uncertainty import MAX_MESH_POINTS

FORMAT = "rrls-reference"
VERSION = 1
#: rrls's default physics: Gymnasium v5 envs, rrls's parameter semantics (docs/differences.md)
PHYSICS = V5
#: the paper's: the original code's v5 envs, the original code's writes, the ``np.arange`` mesh
PAPER_PHYSICS = PAPER
METRICS = ("worst_case", "average_case", "dynamic")
COMPARED = ("physics", "uncertainty", "mesh", "endpoint", "episodes")
#: references shipped with rrls, by name (``--reference paper``)
SHIPPED = {
    "paper": "paper_reference.json",
    "quick": "quick_reference.json",
    "hopper-200k": "hopper_200k_reference.json",
    "halfcheetah": "halfcheetah_reference.json",
    "hopper": "hopper_reference.json",
}
_META = ("label", "physics", "mesh", "episodes", "endpoint", "steps", "eval_seed")
VERSION_KEYS = ("rrls", "gymnasium", "mujoco")


class ReferenceError(ValueError):
    """A reference file that cannot be read or does not match the benchmark (one line)."""


@dataclass
class Reference:
    """One protocol's results; ``rows`` as in the file (``task, uncertainty, algorithm,
    metric, mean, std, n_seeds, values``)."""

    label: str
    physics: str
    mesh: int
    episodes: int
    endpoint: bool = True
    steps: int | None = None
    eval_seed: int | None = None
    versions: dict[str, str] = field(default_factory=dict)
    notes: str = ""
    rows: list[dict[str, Any]] = field(default_factory=list)
    path: str | None = None
    #: where the numbers came from: preset, budget, hyper-parameters, rrls commit, the library
    #: versions and machines of the runs (``export_reference``); shown by the report
    provenance: dict[str, Any] = field(default_factory=dict)

    @property
    def sets(self) -> list[str]:
        return sorted({r["uncertainty"] for r in self.rows})

    def tasks(self, uncertainty: str) -> list[str]:
        return list(dict.fromkeys(r["task"] for r in self.rows if r["uncertainty"] == uncertainty))

    def algorithms(self) -> list[str]:
        return list(dict.fromkeys(r["algorithm"] for r in self.rows))

    def cell(self, task: str, uncertainty: str, algo: str, metric: str) -> dict[str, Any] | None:
        """The row of ``(task, set, algorithm, metric)``, or ``None``."""
        for row in self.rows:
            if (row["task"], row["uncertainty"], row["algorithm"], row["metric"]) == (
                task,
                uncertainty,
                algo,
                metric,
            ):
                return row
        return None

    def mean(self, task: str, uncertainty: str, algo: str, metric: str) -> float | None:
        row = self.cell(task, uncertainty, algo, metric)
        return None if row is None else float(row["mean"])

    def describe(self) -> dict[str, Any]:
        """The metadata (what the report records about the reference it used)."""
        return {
            "label": self.label,
            "physics": self.physics,
            "mesh": self.mesh,
            "episodes": self.episodes,
            "endpoint": self.endpoint,
            "steps": self.steps,
            "eval_seed": self.eval_seed,
            "versions": dict(self.versions),
            "file": self.path,
            "provenance": dict(self.provenance),
        }

    # --- files ---------------------------------------------------------------------------------
    def to_json(self) -> dict[str, Any]:
        return {
            "format": FORMAT,
            "version": VERSION,
            **{k: getattr(self, k) for k in _META},
            "versions": dict(self.versions),
            "notes": self.notes,
            "provenance": self.provenance,
            "rows": [_clean_row(r) for r in self.rows],
        }

    def save(self, path: str | Path) -> Path:
        """Write ``path`` atomically: JSON for ``.json``, else CSV."""
        from rrls.files import atomic_write_bytes, atomic_write_json

        path = Path(path)
        if path.suffix.lower() == ".json":
            return atomic_write_json(path, self.to_json())
        import io

        import pandas as pd

        lines = []
        for row in self.rows:
            values = row.get("values")
            lines.append(
                {
                    **{k: row[k] for k in ("task", "uncertainty", "algorithm", "metric")},
                    "mean": row["mean"],
                    "std": row.get("std"),
                    "n_seeds": row.get("n_seeds"),
                    "values": ";".join(repr(float(v)) for v in values) if values else "",
                    "seeds": ";".join(str(s) for s in row.get("seeds") or ()),
                    **{k: getattr(self, k) for k in _META},
                    **{f"{k}_version": self.versions.get(k, "") for k in VERSION_KEYS},
                }
            )
        buf = io.StringIO()
        pd.DataFrame(lines).to_csv(buf, index=False)  # shortest repr: round-trips exactly
        return atomic_write_bytes(path, buf.getvalue().encode())


def _clean_row(row: dict[str, Any]) -> dict[str, Any]:
    out = {k: row[k] for k in ("task", "uncertainty", "algorithm", "metric")}
    out["mean"] = float(row["mean"])
    out["std"] = None if row.get("std") is None else float(row["std"])
    out["n_seeds"] = None if row.get("n_seeds") is None else int(row["n_seeds"])
    values = row.get("values")
    out["values"] = None if values is None else [float(v) for v in values]
    if row.get("seeds") is not None:  # optional: which seed each value is (older files lack it)
        out["seeds"] = [int(s) for s in row["seeds"]]
    return out


def _fail(path: Any, message: str) -> ReferenceError:
    return ReferenceError(f"{path}: not a usable reference file ({message})")


_ROW_SCHEMA = Schema(
    {
        "task": string(required=True),
        "uncertainty": string(required=True),
        "algorithm": string(required=True),
        "metric": string(choices=METRICS, required=True),
        "mean": number(required=True),
        "std": number(0, null=True),
        "n_seeds": integer(1, MAX_SEEDS, null=True),
        "values": array(number(), max_items=MAX_SEEDS, null=True),
        "seeds": array(integer(0, MAX_SEED), max_items=MAX_SEEDS, null=True),
    }
)
_OPEN = Schema({}, open=True)
#: a reference file (JSON; a CSV's lines are read into the same object first)
REFERENCE_SCHEMA = Schema(
    {
        "format": string(choices=(FORMAT,), required=True),
        "version": integer(choices=(VERSION,), required=True),
        "label": string(required=True),
        "physics": string(choices=tuple(ALIASES), required=True),
        "mesh": integer(1, MAX_MESH_POINTS, required=True),
        "episodes": integer(1, MAX_EPISODES, required=True),
        "endpoint": boolean(),
        "steps": integer(0, 10**12, null=True),
        "eval_seed": integer(0, MAX_SEED, null=True),
        "versions": obj(_OPEN),
        "notes": string(),
        "provenance": obj(_OPEN),
        "rows": array(obj(_ROW_SCHEMA), required=True),
    }
)


def load_reference(path: str | Path) -> Reference:
    """Read a reference file (JSON or CSV), or a shipped one by name (``paper``)."""
    if str(path) in SHIPPED:
        text = resources.files("rrls.report").joinpath(SHIPPED[str(path)]).read_text()
        ref = _from_json(loads_json(text, str(path)), str(path))
        ref.path = str(path)
        return ref
    path = Path(path)
    if not path.is_file():
        raise ReferenceError(
            f"no reference file {path} (a .json or .csv; shipped: {', '.join(SHIPPED)})"
        )
    if path.suffix.lower() == ".json":
        try:
            data = read_json(path)
        except JsonError as err:
            why = err.reason.replace("not valid JSON", "invalid JSON") if err.syntax else err.reason
            raise _fail(path, why) from None
        ref = _from_json(data, path)
    else:
        ref = _from_json(_csv_as_json(path), path)
    ref.path = str(path)
    return ref


def _from_json(data: Any, path: Any) -> Reference:
    """A reference from its JSON object, checked against ``REFERENCE_SCHEMA`` (one line
    naming the file, the field and the value) and for rows that agree with themselves."""
    try:
        REFERENCE_SCHEMA.check(data, str(path))
    except SchemaError as err:
        raise ReferenceError(f"{err} (not a usable reference file)") from None
    rows = [_clean_row(r) for r in data["rows"]]
    for i, row in enumerate(rows):
        if row["values"] is not None and row["n_seeds"] not in (None, len(row["values"])):
            raise _fail(
                path,
                f"rows[{i}]: n_seeds is {row['n_seeds']} but it holds {len(row['values'])} values",
            )
        seeds = row.get("seeds")
        if seeds is not None and (row["values"] is None or len(seeds) != len(row["values"])):
            raise _fail(
                path, f"rows[{i}]: {len(seeds)} seeds for {len(row['values'] or ())} values"
            )
    return Reference(
        label=data["label"],
        physics=physics_label(data["physics"]),
        mesh=data["mesh"],
        episodes=data["episodes"],
        endpoint=data.get("endpoint", True),
        steps=data.get("steps"),
        eval_seed=data.get("eval_seed"),
        versions={k: str(v) for k, v in (data.get("versions") or {}).items()},
        notes=data.get("notes", ""),
        rows=rows,
        provenance=dict(data.get("provenance") or {}),
    )


def _csv_as_json(path: Path) -> dict[str, Any]:
    """A CSV reference as the JSON object it stands for: the metadata columns (the same on
    every line) at the top, each line a row with ``values`` split at ``;``."""
    import pandas as pd

    try:
        frame = pd.read_csv(
            path, keep_default_na=False, na_values=[""], dtype={"values": str, "seeds": str}
        )
    except Exception as err:  # noqa: BLE001 - any unreadable table: one line naming it
        raise _fail(path, f"unreadable CSV: {err}") from None
    data: dict[str, Any] = {"format": FORMAT, "version": VERSION, "versions": {}}
    for col in (*_META, *(f"{k}_version" for k in VERSION_KEYS)):
        if col not in frame.columns:
            continue
        distinct = frame[col].dropna().unique()
        if len(distinct) > 1:
            raise _fail(path, f"column {col} differs between rows (one protocol per file)")
        if len(distinct):
            value = distinct[0].item() if hasattr(distinct[0], "item") else distinct[0]
            if col.endswith("_version"):
                data["versions"][col.removesuffix("_version")] = str(value)
            else:
                data[col] = _csv_int(REFERENCE_SCHEMA, col, value)
    rows = []
    row_columns = [c for c in _ROW_SCHEMA.fields if c in frame.columns]
    for i, rec in enumerate(frame[row_columns].to_dict("records")):
        row = {k: None if _missing(v) else _csv_int(_ROW_SCHEMA, k, v) for k, v in rec.items()}
        text = row.get("values")
        try:
            row["values"] = [float(v) for v in str(text).split(";")] if text else None
        except ValueError:
            raise _fail(path, f"line {i + 2}: values {text!r} are not numbers") from None
        text = row.pop("seeds", None)
        if text:
            try:
                row["seeds"] = [int(s) for s in str(text).split(";")]
            except ValueError:
                raise _fail(path, f"line {i + 2}: seeds {text!r} are not integers") from None
        rows.append(row)
    data["rows"] = rows
    return data


def _csv_int(schema: Schema, name: str, value: Any) -> Any:
    """A CSV column of integers with an empty cell reads as floats: ``10.0`` back to ``10``
    where the field is an integer (a CSV cannot say which it was)."""
    if schema.fields[name].kind == "int" and isinstance(value, float) and value.is_integer():
        return int(value)
    return value


def _missing(value: Any) -> bool:
    return value is None or (isinstance(value, float) and math.isnan(value))


# --- a benchmark and a reference --------------------------------------------------------------
def benchmark_protocol(spec: dict[str, Any]) -> dict[str, Any]:
    """What a reference must share with a benchmark (``benchmark.json``'s content, its
    protocol whole or, as ``Benchmark.flat_json`` gives it, flat)."""
    if isinstance(spec.get("protocol"), dict):
        spec = {**spec, **spec["protocol"]}
    physics = physics_label(spec.get("physics"))
    endpoint = spec.get("endpoint")  # None (or absent): the physics' default, as Protocol
    return {
        "physics": physics,
        "uncertainty": spec["uncertainty"],
        "mesh": int(spec["mesh"]),
        "endpoint": physics != PAPER if endpoint is None else bool(endpoint),
        "episodes": int(spec["episodes"]),
    }


def check_compatible(ref: Reference, spec: dict[str, Any], other_budget: bool = False) -> None:
    """Refuse (``ReferenceError``, one line naming each field) a reference measured under
    another protocol than the benchmark ``spec``, holding none of its tasks, or (unless
    ``other_budget``) trained with another budget than the benchmark's."""
    mine = benchmark_protocol(spec)
    theirs = {
        "physics": ref.physics,
        "uncertainty": mine["uncertainty"] if mine["uncertainty"] in ref.sets else ref.sets,
        "mesh": ref.mesh,
        "endpoint": ref.endpoint,
        "episodes": ref.episodes,
    }
    diff = [k for k in COMPARED if theirs[k] != mine[k]]
    if diff:
        detail = "; ".join(f"{k}: {theirs[k]!r} there, {mine[k]!r} here" for k in diff)
        raise ReferenceError(
            f"reference {ref.path or ref.label!r} ({ref.label}) was measured under another "
            f"protocol than this benchmark ({detail}): its numbers are not comparable"
        )
    steps = spec.get("steps")
    if not other_budget and steps is not None and ref.steps != steps:
        theirs_text = f"{ref.steps:,} training steps per run" if ref.steps else "no budget stated"
        raise ReferenceError(
            f"reference {ref.path or ref.label!r} ({ref.label}) has {theirs_text}, this benchmark "
            f"{steps:,}: its rows are not like-for-like; --allow-other-budget shows them marked "
            "‡ and normalised by the reference's own TD3 and M2TD3"
        )
    common = [t for t in spec["tasks"] if t in ref.tasks(mine["uncertainty"])]
    if not common:
        raise ReferenceError(
            f"reference {ref.path or ref.label!r} has no results for this benchmark's tasks "
            f"({', '.join(spec['tasks'])}) on set {mine['uncertainty']}; it has: "
            f"{', '.join(ref.tasks(mine['uncertainty'])) or 'none'}"
        )


def paper_reference_from_results(paper: dict[str, Any]) -> Reference:
    """The paper's published tables (``paper_results.json``) as a reference (other physics)."""
    tables = (("worst_case", "raw_worst_case"), ("average_case", "raw_average_case"))
    rows = [
        {
            "task": task,
            "uncertainty": paper["uncertainty"],
            "algorithm": algo,
            "metric": metric,
            "mean": mean,
            "std": std,
            "n_seeds": paper["seeds"],
            "values": None,
        }
        for metric, table in (*tables, ("dynamic", "dynamic"))
        for algo, cells in paper[table].items()
        for task, (mean, std) in cells.items()
    ]
    return Reference(
        label="paper, other physics",
        physics=PAPER_PHYSICS,
        mesh=10,
        episodes=5,
        endpoint=False,  # the original code's np.arange mesh (docs/differences.md)
        steps=int(paper["steps"]),
        eval_seed=None,
        versions={},
        notes="The RRLS paper's published tables (raw worst / average case, Appendix Tables 7-8; "
        "Table 6): the original code's v5 envs, floor-only friction, np.arange mesh "
        "(docs/differences.md). Not a reference for rrls's default physics (v5).",
        rows=rows,
    )
