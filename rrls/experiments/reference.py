"""Reference results as data: the one module that knows the reference file format.

A reference is what a lab (or the paper) measured under one evaluation protocol: per task, set
and algorithm, the worst-case and average-case (and dynamic) mean over seeds, with the std, the
number of seeds and, when known, the per-seed values. ``rrls report DIR --reference FILE``
normalises a task with the reference's TD3 and M2TD3 when the benchmark has not trained its own,
and ``rrls report DIR --export-reference FILE`` writes a benchmark's results as such a file.

A reference is only a reference for a benchmark that measures the same thing: the same
``physics``, uncertainty set, mesh (points per dimension, endpoint) and episodes per point;
anything else is refused (``ReferenceError``, one line naming the fields). The training budget
(``steps``) may differ; the report says so.

JSON (``.json``)::

    {"format": "rrls-reference", "version": 1, "label": "...", "physics": "v5",
     "mesh": 10, "episodes": 5, "endpoint": true, "steps": 20000, "eval_seed": 0,
     "versions": {"rrls": "...", "gymnasium": "...", "mujoco": "..."}, "notes": "...",
     "rows": [{"task": "hopper", "uncertainty": "3d", "algorithm": "td3",
               "metric": "worst_case", "mean": 69.3, "std": 42.77, "n_seeds": 10,
               "values": [...] or null}, ...]}

CSV (any other suffix): one line per row with the same columns, the metadata repeated on every
line (``label, physics, mesh, episodes, endpoint, steps, eval_seed, rrls_version,
gymnasium_version, mujoco_version``) and ``values`` as ``;``-separated numbers (or empty).
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

from rrls.physics import PAPER, V5, physics_label

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
    "hopper": "hopper_reference.json",
}
_META = ("label", "physics", "mesh", "episodes", "endpoint", "steps", "eval_seed")
_VERSION_KEYS = ("rrls", "gymnasium", "mujoco")


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
        from rrls._io import atomic_write_bytes, atomic_write_json

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
                    **{k: getattr(self, k) for k in _META},
                    **{f"{k}_version": self.versions.get(k, "") for k in _VERSION_KEYS},
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
    return out


def _fail(path: Any, message: str) -> ReferenceError:
    return ReferenceError(f"{path}: not a usable reference file ({message})")


def _check_rows(rows: list[dict[str, Any]], path: Any) -> list[dict[str, Any]]:
    out = []
    for i, row in enumerate(rows):
        missing = [
            k for k in ("task", "uncertainty", "algorithm", "metric", "mean") if k not in row
        ]
        if missing:
            raise _fail(path, f"row {i} lacks {', '.join(missing)}")
        if row["metric"] not in METRICS:
            raise _fail(
                path, f"row {i}: unknown metric {row['metric']!r}; valid: {', '.join(METRICS)}"
            )
        try:
            clean = _clean_row(row)
        except (TypeError, ValueError) as err:
            raise _fail(path, f"row {i}: {err}") from None
        if not math.isfinite(clean["mean"]):
            raise _fail(path, f"row {i}: mean is {clean['mean']}")
        out.append(clean)
    return out


def load_reference(path: str | Path) -> Reference:
    """Read a reference file (JSON or CSV), or a shipped one by name (``paper``)."""
    if str(path) in SHIPPED:
        text = resources.files("rrls.experiments").joinpath(SHIPPED[str(path)]).read_text()
        ref = _from_json(json.loads(text), str(path))
        ref.path = str(path)
        return ref
    path = Path(path)
    if not path.is_file():
        raise ReferenceError(
            f"no reference file {path} (a .json or .csv; shipped: {', '.join(SHIPPED)})"
        )
    if path.suffix.lower() == ".json":
        try:
            data = json.loads(path.read_text())
        except (ValueError, UnicodeDecodeError) as err:
            raise _fail(path, f"invalid JSON: {err}") from None
        ref = _from_json(data, path)
    else:
        ref = _from_csv(path)
    ref.path = str(path)
    return ref


def _from_json(data: Any, path: Any) -> Reference:
    if not isinstance(data, dict) or data.get("format") != FORMAT:
        raise _fail(path, f"'format' is not {FORMAT!r}")
    if data.get("version") != VERSION:
        raise _fail(path, f"version {data.get('version')!r}; this rrls reads {VERSION}")
    missing = [k for k in ("label", "physics", "mesh", "episodes", "rows") if k not in data]
    if missing:
        raise _fail(path, f"missing {', '.join(missing)}")
    return Reference(
        label=str(data["label"]),
        physics=_physics(data["physics"], path),
        mesh=int(data["mesh"]),
        episodes=int(data["episodes"]),
        endpoint=bool(data.get("endpoint", True)),
        steps=None if data.get("steps") is None else int(data["steps"]),
        eval_seed=None if data.get("eval_seed") is None else int(data["eval_seed"]),
        versions={k: str(v) for k, v in (data.get("versions") or {}).items()},
        notes=str(data.get("notes", "")),
        rows=_check_rows(list(data["rows"]), path),
        provenance=dict(data.get("provenance") or {}),
    )


def _from_csv(path: Path) -> Reference:
    import pandas as pd

    try:
        frame = pd.read_csv(path, keep_default_na=False, na_values=[""], dtype={"values": str})
    except Exception as err:  # noqa: BLE001 - any unreadable table: one line naming it
        raise _fail(path, f"unreadable CSV: {err}") from None
    need = ["task", "uncertainty", "algorithm", "metric", "mean", "label", "physics"]
    need += ["mesh", "episodes"]
    missing = [c for c in need if c not in frame.columns]
    if missing:
        raise _fail(path, f"missing columns {', '.join(missing)}")
    meta: dict[str, Any] = {}
    for col in (*_META, *(f"{k}_version" for k in _VERSION_KEYS)):
        if col not in frame.columns:
            continue
        distinct = frame[col].dropna().unique()
        if len(distinct) > 1:
            raise _fail(path, f"column {col} differs between rows (one protocol per file)")
        meta[col] = (
            distinct[0].item()
            if len(distinct) and hasattr(distinct[0], "item")
            else (distinct[0] if len(distinct) else None)
        )
    rows = []
    for rec in frame.to_dict("records"):
        values = rec.get("values")
        rec["values"] = (
            [float(v) for v in str(values).split(";")]
            if isinstance(values, str) and values
            else None
        )
        rec["std"] = None if _missing(rec.get("std")) else rec.get("std")
        rec["n_seeds"] = None if _missing(rec.get("n_seeds")) else rec.get("n_seeds")
        rows.append(rec)
    return Reference(
        label=str(meta["label"]),
        physics=_physics(meta["physics"], path),
        mesh=int(meta["mesh"]),
        episodes=int(meta["episodes"]),
        endpoint=_bool(meta.get("endpoint", True)),
        steps=None if _missing(meta.get("steps")) else int(meta["steps"]),
        eval_seed=None if _missing(meta.get("eval_seed")) else int(meta["eval_seed"]),
        versions={
            k: str(meta[f"{k}_version"])
            for k in _VERSION_KEYS
            if not _missing(meta.get(f"{k}_version"))
        },
        rows=_check_rows(rows, path),
    )


def _physics(value: Any, path: Any) -> str:
    """The physics label a file gives (older labels read as today's)."""
    try:
        return physics_label(str(value))
    except ValueError as err:
        raise ReferenceError(f"{path}: {err}") from None


def _missing(value: Any) -> bool:
    return value is None or (isinstance(value, float) and math.isnan(value))


def _bool(value: Any) -> bool:
    if isinstance(value, str):
        return value.strip().lower() in ("true", "1", "yes")
    return bool(value) if not _missing(value) else True


# --- a benchmark and a reference --------------------------------------------------------------
def benchmark_protocol(spec: dict[str, Any]) -> dict[str, Any]:
    """What a reference must share with a benchmark (``benchmark.json``'s content)."""
    physics = physics_label(spec.get("physics"))
    endpoint = spec.get("endpoint")  # None (or absent): the physics' default, as Protocol
    return {
        "physics": physics,
        "uncertainty": spec["uncertainty"],
        "mesh": int(spec["mesh"]),
        "endpoint": physics != PAPER if endpoint is None else bool(endpoint),
        "episodes": int(spec["episodes"]),
    }


def check_compatible(ref: Reference, spec: dict[str, Any]) -> None:
    """Refuse (``ReferenceError``, one line naming each field) a reference measured under
    another protocol than the benchmark ``spec``, or holding none of its tasks."""
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
    common = [t for t in spec["tasks"] if t in ref.tasks(mine["uncertainty"])]
    if not common:
        raise ReferenceError(
            f"reference {ref.path or ref.label!r} has no results for this benchmark's tasks "
            f"({', '.join(spec['tasks'])}) on set {mine['uncertainty']}; it has: "
            f"{', '.join(ref.tasks(mine['uncertainty'])) or 'none'}"
        )


def export_reference(
    root: str | Path, path: str | Path, label: str | None = None, algos: list[str] | None = None
) -> Reference:
    """Write the results of the benchmark in ``root`` (every algorithm, or ``algos``) as a
    reference file another lab can normalise and compare with; returns it."""
    from rrls.experiments import benchfile, stats
    from rrls.experiments.store import load_store

    root = Path(root)
    spec = benchfile.read_spec_json(root)
    tables = load_store(root)
    ev, dyn = tables["evaluations"], tables["dynamic"]
    if not len(ev):
        raise ReferenceError(f"{root} holds no finished run to export")
    scores = stats.per_seed_scores(ev)
    wanted = list(dict.fromkeys(algos or scores["algorithm"]))
    unknown = [a for a in wanted if a not in set(scores["algorithm"])]
    if unknown:
        raise ReferenceError(
            f"no runs of {', '.join(unknown)} in {root}; it has: "
            f"{', '.join(dict.fromkeys(scores['algorithm']))}"
        )
    rows = []
    for (task, algo), group in scores.groupby(["task", "algorithm"], sort=True):
        if algo not in wanted:
            continue
        group = group.sort_values("seed")
        for metric in ("worst_case", "average_case"):
            rows.append(_row(task, spec["uncertainty"], algo, metric, group[metric].to_numpy()))
        if len(dyn):
            sel = dyn[(dyn["task"] == task) & (dyn["algorithm"] == algo)]
            if len(sel):
                per_seed = sel.groupby("seed")["return"].mean().to_numpy()
                rows.append(_row(task, spec["uncertainty"], algo, "dynamic", per_seed))
    versions = {}
    for key in _VERSION_KEYS:
        col = f"{key}_version"
        if col in ev:
            versions[key] = "/".join(sorted(map(str, ev[col].unique())))
    proto = benchmark_protocol(spec)
    ref = Reference(
        label=label or f"{root.resolve().name} ({spec.get('preset', 'custom')} preset)",
        physics=proto["physics"],
        mesh=proto["mesh"],
        episodes=proto["episodes"],
        endpoint=proto["endpoint"],
        steps=int(spec["steps"]),
        eval_seed=int(spec.get("eval_seed", 0)),
        versions=versions,
        notes=f"exported by `rrls report --export-reference` from {root.resolve().name}",
        rows=rows,
        provenance=provenance(root, spec, wanted),
    )
    ref.save(path)
    ref.path = str(path)
    return ref


def provenance(root: Path, spec: dict[str, Any], algos: list[str]) -> dict[str, Any]:
    """Where a benchmark's numbers came from, from its spec and its runs' ``run.json``: the
    preset, budget and hyper-parameters, and every rrls commit, library version, machine and
    device that trained a run (more than one value: the runs were produced in pieces)."""
    from rrls import __version__, rundir

    runs: dict[str, Any] = {}
    for directory in sorted(p for p in (root / "runs").glob("*") if p.is_dir()):
        run: dict[str, Any] = {}
        for name in (rundir.RESULT, "run.json"):  # run.json (training) has the machine
            try:
                run.update(json.loads((directory / name).read_text()))
            except (OSError, ValueError):
                continue
        if run.get("algorithm") in algos:
            runs[directory.name] = run

    def distinct(values: Any) -> list[Any]:
        out: list[Any] = []
        for v in values:
            if v is not None and v not in out:
                out.append(v)
        return out

    versions: dict[str, list[str]] = {}
    for run in runs.values():
        for key, value in (run.get("versions") or {}).items():
            versions.setdefault(key, [])
            if value not in versions[key]:
                versions[key].append(value)
    prov = [run.get("provenance") or {} for run in runs.values()]
    return {
        "preset": spec.get("preset"),
        "physics": spec.get("physics"),
        "uncertainty": spec.get("uncertainty"),
        "steps": spec.get("steps"),
        "seeds": spec.get("seeds"),
        "learning_starts": spec.get("learning_starts"),
        "hidden": spec.get("hidden"),
        "learning_rate": spec.get("learning_rate"),
        "batch_size": spec.get("batch_size"),
        "mesh": spec.get("mesh"),
        "episodes": spec.get("episodes"),
        "dynamic_episodes": spec.get("dynamic_episodes"),
        "runs": len(runs),
        "exported_with_rrls": __version__,
        "versions": {k: sorted(map(str, v)) for k, v in sorted(versions.items())},
        "commits": distinct(p.get("commit") for p in prov),
        "machines": distinct(p.get("machine") for p in prov),
        "devices": distinct(p.get("device") for p in prov),
    }


def _row(task: str, uncertainty: str, algo: str, metric: str, values: Any) -> dict[str, Any]:
    import numpy as np

    values = np.asarray(values, dtype=float)
    return {
        "task": task,
        "uncertainty": uncertainty,
        "algorithm": algo,
        "metric": metric,
        "mean": float(values.mean()),
        "std": float(values.std()),
        "n_seeds": len(values),
        "values": [float(v) for v in values],
    }


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
