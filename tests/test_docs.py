"""The README's recipes run, its links resolve, and the documentation site builds (issue 27).

Every code block of the README's four recipes runs here: Python blocks as written, with the
evaluation shrunk to a tiny mesh and short episodes; every `rrls` command of a shell block is
parsed by the real command-line parser (a misspelt flag or value fails), and the commands of the
comparison recipe (submit, then report against the shipped `quick` reference) run for real,
since they take seconds.
"""

from __future__ import annotations

import importlib.util
import inspect
import json
import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[1]
README = REPO / "README.md"
DOCS = REPO / "docs"
BLOCK = re.compile(r"^```(\w+)\n(.*?)^```", re.S | re.M)
LINK = re.compile(r"\]\(([^)\s]+)\)")


def section(text: str, heading: str) -> str:
    """The text under ``heading`` (a whole line) up to the next heading of the same level."""
    level = heading.split(" ")[0]
    start = text.index(f"\n{heading}\n") + len(heading) + 2
    end = text.find(f"\n{level} ", start)
    return text[start : end if end >= 0 else None]


def recipes() -> dict[str, list[tuple[str, str]]]:
    """The README's recipes: ``{title: [(language, code), ...]}``."""
    body = section(README.read_text(), "## Recipes")
    parts = re.split(r"^### (.+)$", body, flags=re.M)[1:]
    return {
        title: [(m.group(1), m.group(2)) for m in BLOCK.finditer(text)]
        for title, text in zip(parts[::2], parts[1::2])
    }


def commands(code: str) -> list[list[str]]:
    """The ``rrls`` command lines of a shell block, comments removed."""
    lines = [shlex.split(line, comments=True) for line in code.splitlines()]
    return [argv for argv in lines if argv]


@pytest.fixture
def tiny_evaluate(monkeypatch):
    """``rrls.evaluation.evaluate`` on a 2-point mesh, 1 episode of 20 steps, in-process."""
    import rrls.evaluation

    real = rrls.evaluation.evaluate
    mesh_keyword = "mesh" if "mesh" in inspect.signature(real).parameters else "nb_mesh_dim"
    calls = []

    def tiny(*args, **kwargs):
        small = {mesh_keyword: 2, "episodes": 1, "max_episode_steps": 20}
        if len(args) > 2 and isinstance(args[2], rrls.evaluation.Protocol):  # the protocol form
            args = (*args[:2], args[2].replace(**small))
        else:
            kwargs.update(small)
        kwargs.update(workers=1, progress=False)
        result = real(*args, **kwargs)
        calls.append(result)
        return result

    monkeypatch.setattr(rrls.evaluation, "evaluate", tiny)
    return calls


def test_the_readme_has_four_recipes_each_with_code():
    found = recipes()
    assert len(found) == 4, list(found)
    for title, blocks in found.items():
        assert blocks and all(lang in ("python", "bash") for lang, _ in blocks), title


def test_the_readme_python_recipes_run(tiny_evaluate, tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    blocks = [code for found in recipes().values() for lang, code in found if lang == "python"]
    assert len(blocks) >= 2
    for code in blocks:
        exec(compile(code, str(README), "exec"), {"__name__": "readme_recipe"})
    assert len(tiny_evaluate) == 1  # the worst-case recipe evaluated once
    result = tiny_evaluate[0]
    assert len(result.per_point) == 2**3 and np.isfinite(result.worst_case)
    out = capsys.readouterr().out
    assert "torsomass" in out and f"{result.worst_case}" in out


def test_every_rrls_command_of_the_recipes_parses():
    from rrls.cli import build_parser

    parser = build_parser(with_train=True)
    seen = []
    for title, blocks in recipes().items():
        for lang, code in blocks:
            if lang != "bash":
                continue
            for argv in commands(code):
                assert argv[0] == "rrls", (title, argv)
                try:
                    parser.parse_args(argv[1:])
                except SystemExit as err:
                    pytest.fail(f"{title}: `{shlex.join(argv)}` does not parse ({err})")
                seen.append(argv[1])
    assert {"train", "evaluate", "benchmark", "submit", "report"} <= set(seen)


@pytest.mark.e2e
def test_the_comparison_recipe_runs_and_writes_latex_beside_the_reference(tmp_path, monkeypatch):
    pytest.importorskip("scipy")
    from rrls.cli import main
    from rrls.evaluation import MLPPolicy

    monkeypatch.chdir(tmp_path)
    rng = np.random.default_rng(0)  # an InvertedPendulum policy: 4 observations, 1 action
    weights = [rng.normal(0, 0.1, (4, 8)), rng.normal(0, 0.1, (8, 1))]
    MLPPolicy(weights, [np.zeros(8), np.zeros(1)], action_scale=3.0).save("my_policy.npz")
    (title,) = [t for t in recipes() if "LaTeX" in t]
    argvs = [argv for lang, code in recipes()[title] if lang == "bash" for argv in commands(code)]
    assert [argv[1] for argv in argvs] == ["submit", "report"]
    for argv in argvs:
        assert main(argv[1:]) == 0, argv
    report = Path(argvs[-1][2]) / "report"
    summary = json.loads((report / "summary.json").read_text())
    assert summary["normalisation"]["invertedpendulum"]["worst_case"] == "reference"
    assert summary["results"]["invertedpendulum"]["my-method"]["worst_case"]["n_seeds"] == 1
    assert "TD3" in (report / "report.md").read_text()  # the reference's rows
    assert "\\toprule" in (report / "tables" / "raw_worst_case.tex").read_text()


def test_the_faq_python_blocks_run():
    blocks = [m.group(2) for m in BLOCK.finditer((DOCS / "faq.md").read_text())]
    assert blocks and "get_wrapper_attr" in blocks[0]
    for code in blocks:  # each in a fresh interpreter: the imports it needs are in the block
        subprocess.run([sys.executable, "-c", code], check=True, capture_output=True, text=True)


def slug(heading: str) -> str:
    """Python-Markdown's ``toc`` anchor of a heading (as MkDocs and GitHub write it for ours)."""
    text = re.sub(r"[^\w\s-]", "", heading.strip().lower())
    return re.sub(r"[-\s]+", "-", text).strip("-")


def test_the_readme_links_resolve_to_files_and_anchors():
    links = [link for link in LINK.findall(README.read_text()) if "://" not in link]
    assert len(links) >= 10
    for link in links:
        path, _, anchor = link.partition("#")
        target = (REPO / path).resolve()
        assert target.is_file(), f"README.md links to {link}, which does not exist"
        if anchor:
            headings = re.findall(r"^#+ (.+)$", target.read_text(), flags=re.M)
            assert anchor in {slug(h) for h in headings}, f"README.md: no anchor {link}"


def test_the_readme_stays_a_landing_page():
    text = README.read_text()
    assert len(text.splitlines()) <= 160
    setup = section(text, "## Set-up (a fresh machine with Python ≥ 3.10 and pip)")
    assert [code.strip() for _, code in BLOCK.findall(setup)] == [
        'python3 -m pip install -c constraints.txt ".[train]" && rrls quickstart',
        'python3 -m pip install -c constraints.txt ".[test]" && python3 -m pytest',
    ]
    # .ci/run runs the README's test command verbatim
    assert (
        'python3 -m pip install -c constraints.txt ".[test]" && python3 -m pytest'
        in (REPO / ".ci" / "run").read_text()
    )


def test_the_tutorials_index_lists_every_tutorial():
    index = (DOCS / "tutorials" / "README.md").read_text()
    scripts = sorted(p.name for p in (DOCS / "tutorials").glob("*.py"))
    assert len(scripts) >= 3
    for name in scripts:
        assert f"[`{name}`]({name})" in index, name


@pytest.mark.e2e
@pytest.mark.skipif(
    importlib.util.find_spec("mkdocs") is None, reason='needs the docs extra: pip install ".[docs]"'
)
def test_the_documentation_site_builds_strictly(tmp_path):
    """Warnings are errors: a broken link or anchor, a page missing from the nav, a docstring
    mkdocstrings cannot render."""
    proc = subprocess.run(
        [sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(tmp_path)],
        cwd=REPO,
        env={**os.environ, "NO_MKDOCS_2_WARNING": "1"},
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert (tmp_path / "api" / "rrls.evaluation" / "index.html").is_file()
    assert (tmp_path / "faq" / "index.html").is_file()
