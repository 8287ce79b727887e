"""The house rules of ``../shared/DESIGN.md``, checked on the source: no import circle anywhere
(imports inside functions count: they only defer one), and layers point one way."""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1] / "rrls"
#: each layer may import only itself and the layers before it (modules not listed: the base).
#: The pipeline in folders: tasks as envs, wrapped, evaluated, trained on; a benchmark of runs;
#: submissions entered into one; the report of its results; the command line over all.
LAYERS = ("envs", "wrappers", "evaluation", "agents", "benchmark", "submissions", "report", "cli")
#: kept only as deprecated import paths (``rrls.deprecation.moved_modules``): they hold no code
SHIMS = ("rrls.experiments",)


def _modules() -> dict[str, Path]:
    mods = {}
    for path in ROOT.rglob("*.py"):
        parts = list(path.relative_to(ROOT.parent).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        mods[".".join(parts)] = path
    return mods


def _graph() -> dict[str, set[str]]:
    mods = _modules()

    def owner(name: str) -> str | None:
        while name and name not in mods:
            name = name.rpartition(".")[0]
        return name or None

    graph: dict[str, set[str]] = {m: set() for m in mods}
    for mod, path in mods.items():
        for node in ast.walk(ast.parse(path.read_text())):
            names: list[str] = []
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom) and node.module and not node.level:
                names = [
                    f"{node.module}.{a.name}" if f"{node.module}.{a.name}" in mods else node.module
                    for a in node.names
                ]
            for name in names:
                target = owner(name) if name.split(".")[0] == "rrls" else None
                if target and target != mod:
                    graph[mod].add(target)
    return graph


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components of more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    found: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        for w in graph[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                found.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return found


def _layer(mod: str) -> int:
    parts = mod.split(".")
    name = parts[1] if len(parts) > 1 else ""
    return LAYERS.index(name) if name in LAYERS else -1


def test_the_layers_are_the_folders():
    """Every layer is a folder of ``rrls/`` and every folder a layer (or a shim, or the twin,
    which the agents use behind a lazy import): a new folder gets a place in the order."""
    folders = {p.name for p in ROOT.iterdir() if (p / "__init__.py").exists()}
    assert folders == {*LAYERS, *(s.split(".")[1] for s in SHIMS), "twin"}


def test_the_shims_hold_no_code_and_nothing_imports_them():
    graph = _graph()
    for shim in SHIMS:
        assert graph[shim] <= {"rrls.deprecation"}  # the new paths are strings, not imports
        assert not [mod for mod, deps in graph.items() if shim in deps]


def test_the_report_never_imports_training_and_the_benchmark_never_the_report():
    """The report reads a benchmark's files and store only (a results folder copied to a
    machine without torch still reports; the twin's task table is data); a benchmark hands
    its runner the report to write (``runner.benchmark(report=...)``), never importing it."""
    graph = _graph()
    for mod, deps in graph.items():
        if mod.startswith("rrls.report"):
            training = {d for d in deps if d.startswith(("rrls.agents", "rrls.twin"))}
            assert training <= {"rrls.twin.catalog"}, mod  # the twin's table: data, no warp
            assert not {
                d for d in deps if d in {"rrls.benchmark.pipeline", "rrls.benchmark.runner"}
            }
        if mod.startswith(("rrls.benchmark", "rrls.submissions")):
            assert not {d for d in deps if d.startswith("rrls.report")}, mod


def test_the_cycle_finder_finds_a_cycle():
    assert _cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]


def test_no_import_circle_anywhere_inside_functions_too():
    assert _cycles(_graph()) == []


def test_layers_point_one_way():
    back = [
        f"{mod} -> {dep}"
        for mod, deps in _graph().items()
        for dep in deps
        if _layer(mod) >= 0 and _layer(dep) > _layer(mod)
    ]
    assert back == []


def test_the_algorithms_are_leaves_the_table_loads_by_name():
    """``rrls/agents/algos/``: one file per algorithm on the shared infrastructure. Nothing else
    imports them (the table names each learner, ``rrls.agents.lookup`` loads it), except
    ``lookup`` itself for TD3's ``Config`` and ``make_env``, a plug-in's defaults; an algorithm
    may build on another (DR on TD3)."""
    graph = _graph()
    algos = {m for m in graph if m.startswith("rrls.agents.algos.")}
    assert len(algos) == 7
    importers = {mod for mod, deps in graph.items() if deps & algos and mod not in algos}
    assert importers == {"rrls.agents.lookup"}
    above = {"rrls.agents.loop", "rrls.agents.driver", "rrls.agents.run", "rrls.agents.lookup"}
    assert all(not graph[algo] & above for algo in algos)  # the loop drives them, not back
