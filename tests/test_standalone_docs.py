"""The docs and the CLI's messages stand alone: no file outside the repository, no talk of the
project's issue tracker, and every install line one that works from a clone (rrls is not on a
package index: ``python3 -m pip install -c constraints.txt ".[extra]"`` in the checkout)."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
TEXTS = sorted(
    [ROOT / "README.md", *ROOT.glob("docs/**/*.md"), *ROOT.glob("docs/**/*.py")]
    + list(ROOT.glob("rrls/**/*.py"))
)
FORBIDDEN = {
    "a file outside the repository": re.compile(r"\.\./shared|MEASURED\.md|DESIGN\.md"),
    "the issue tracker": re.compile(r"\bissues?\s+\d+|\bthe issue\b|\bissue's\b", re.I),
    "an install from a package index": re.compile(r"pip install\s+[\"']?rrls\["),
}


@pytest.mark.parametrize("what", list(FORBIDDEN))
def test_docs_and_messages_stand_alone(what):
    bad = [
        f"{path.relative_to(ROOT)}:{n}"
        for path in TEXTS
        for n, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1)
        if FORBIDDEN[what].search(line)
    ]
    assert not bad, f"{what}: {', '.join(bad[:10])}"


def test_missing_extras_name_the_install_line_that_works():
    from rrls.extras import install_hint

    assert (
        install_hint("train")
        == 'in the rrls checkout: python3 -m pip install -c constraints.txt ".[train]"'
    )
    from rrls.extras import __doc__ as doc

    assert "constraints.txt" in doc


def test_a_module_attribute_policy_imports_from_the_current_directory(tmp_path):
    import os
    import subprocess
    import sys

    (tmp_path / "mypol.py").write_text(
        "import numpy as np\n\ndef zeros(obs):\n    return np.zeros((len(obs), 1))\n"
    )
    args = ["evaluate", "mypol:zeros", "--task", "invertedpendulum", "--uncertainty", "1d"]
    args += ["--mesh", "2", "--episodes", "1", "--workers", "1", "--out", "out"]
    code = f"import sys; from rrls.cli import main; sys.exit(main({args!r}))"
    # -P: the current directory is not on sys.path, as for the installed `rrls` script
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    proc = subprocess.run(
        [sys.executable, "-P", "-c", code], cwd=tmp_path, capture_output=True, text=True, env=env
    )
    assert proc.returncode == 0, proc.stderr
    assert (tmp_path / "out" / "summary.json").is_file()


@pytest.mark.e2e
def test_rrls_commands_drop_the_shipped_xmls_deprecation_but_user_code_sees_it(tmp_path):
    import os
    import subprocess
    import sys

    env = {k: v for k, v in os.environ.items() if k != "RRLS_QUIET_XML_DEPRECATIONS"}
    env["PYTHONPATH"] = str(ROOT)
    (tmp_path / "cheetah.py").write_text(
        "import numpy as np\n\ndef zeros(obs):\n    return np.zeros((len(obs), 6))\n"
    )
    args = ["evaluate", "cheetah:zeros", "--task", "halfcheetah", "--uncertainty", "1d"]
    args += ["--mesh", "2", "--episodes", "1", "--workers", "2", "--out", "out"]
    code = f"import sys; from rrls.cli import main; sys.exit(main({args!r}))"
    run = dict(cwd=tmp_path, capture_output=True, text=True, env=env)
    proc = subprocess.run([sys.executable, "-c", code], **run)
    assert proc.returncode == 0, proc.stderr
    assert "settotalmass" not in proc.stderr  # the command and its two workers
    user = "import gymnasium as gym, rrls; gym.make('rrls/robust-halfcheetah-v0')"
    proc = subprocess.run([sys.executable, "-W", "always", "-c", user], **run)
    assert "settotalmass' is deprecated" in proc.stderr  # a user's own code still sees it
