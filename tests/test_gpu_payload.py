"""The GPU runbook's payload: wheels slimmed, packed and cut into pieces that fit a call beside
the tree, taken in on the GPU machine over several calls (each piece checked by sha256, kept
outside the tree between calls), and installed whole once the last one is in."""

from __future__ import annotations

import importlib.util
import json
import os
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
MIB = 1 << 20


@pytest.fixture(scope="module")
def payload():
    spec = importlib.util.spec_from_file_location("gpu_payload", ROOT / "benchmarks/gpu_payload.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules["gpu_payload"] = module
    spec.loader.exec_module(module)
    return module


def _wheel(path: Path, members: dict[str, bytes]) -> None:
    with zipfile.ZipFile(path, "w") as z:
        for name, data in members.items():
            z.writestr(name, data)


def test_the_payload_travels_in_pieces_and_installs_whole(tmp_path, payload, capsys):
    blob = os.urandom(300_000)  # incompressible: several pieces of 0.1 MiB
    wheels = tmp_path / "wheels"
    wheels.mkdir()
    _wheel(wheels / "pkg-1.0-py3-none-any.whl", {"pkg/__init__.py": b"X = 1\n", "pkg/blob": blob})
    dropped = {"warp/bin/warp-clang.so": b"llvm", "warp/examples/a.py": b"", "warp/tests/t.py": b""}
    kept = {
        "warp/__init__.py": b"",
        "warp/bin/warp.so": b"cuda",
        "warp_lang-1.0.dist-info/METADATA": b"m",
    }
    _wheel(wheels / "warp_lang-1.0-py3-none-manylinux_2_28_x86_64.whl", {**dropped, **kept})
    here = tmp_path / "here"
    assert (
        payload.main(
            [
                "--gpu-dir",
                str(here),
                "build",
                "--wheels",
                str(wheels),
                "--piece-mib",
                "0.1",
                "--tree-mib",
                "5",
            ]
        )
        == 0
    )
    manifest = json.loads((here / "manifest.json").read_text())
    pieces = manifest["pieces"]
    assert len(pieces) >= 3 and all(p["size"] <= 0.1 * MIB for p in pieces)
    assert sorted(manifest["dropped"]) == sorted(dropped)
    assert "call 1/1: carry" in capsys.readouterr().out  # small pieces: one call carries all

    # the GPU machine: the first call carries the manifest and the first piece only
    there, store = tmp_path / "there" / ".gpu", tmp_path / "store"
    there.mkdir(parents=True)
    shutil.copy(here / "manifest.json", there)
    shutil.copy(here / pieces[0]["name"], there)
    device = ["--gpu-dir", str(there), "device", "--store", str(store), "--install-only"]
    assert payload.main(device) == 0
    said = capsys.readouterr().out
    assert f"1/{len(pieces)} pieces in" in said and pieces[1]["name"] in said
    assert not (store / "site").exists()
    # the next call: the others (the first piece waits in the store, not in the tree)
    (there / pieces[0]["name"]).unlink()
    bad = bytearray((here / pieces[1]["name"]).read_bytes())
    bad[0] ^= 0xFF  # a piece damaged on the way is refused, not installed
    (there / pieces[1]["name"]).write_bytes(bytes(bad))
    for p in pieces[2:]:
        shutil.copy(here / p["name"], there)
    assert payload.main(device) == 0
    said = capsys.readouterr().out
    assert "sha256 differs" in said and f"still to carry: {pieces[1]['name']}" in said
    shutil.copy(here / pieces[1]["name"], there)
    assert payload.main(device) == 0
    assert "installed in" in capsys.readouterr().out
    site = store / "site"
    assert (site / "pkg" / "blob").read_bytes() == blob
    assert (site / "warp" / "bin" / "warp.so").read_bytes() == b"cuda"
    assert (site / "warp_lang-1.0.dist-info" / "METADATA").exists()
    assert not [p for p in dropped if (site / p).exists()]
    assert payload.main(device) == 0  # a later call finds it installed: nothing unpacked again


def test_the_calls_carry_the_pieces_beside_the_tree(payload):
    def pieces(*mib):
        return [
            {"name": f"payload.part{i:02d}", "size": int(m * MIB)} for i, m in enumerate(mib, 1)
        ]

    # 58 MiB of room beside a 5 MiB tree: 30 + 20 share a call, 10 does not fit with them
    assert payload.calls(pieces(30, 20, 10), tree=5 * MIB) == [
        ["payload.part01", "payload.part02"],
        ["payload.part03"],
    ]
    assert len(payload.calls(pieces(50, 50, 20), tree=5 * MIB)) == 3
    with pytest.raises(ValueError, match=r"beside the tree \(61.0 MiB\)"):
        payload.calls(pieces(50), tree=61 * MIB)


def test_the_pinned_wheels_are_within_the_warp_extra(payload):
    """The payload carries the versions the twin is tested with (pyproject's ``warp`` extra)."""
    import tomllib

    requirements = pytest.importorskip("packaging.requirements")
    extra = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["optional-dependencies"]
    pins = dict(w.split("==") for w in payload.WHEELS)
    for line in extra["warp"]:
        req = requirements.Requirement(line)
        assert req.specifier.contains(pins[req.name]), (req, pins[req.name])
    assert pins["mujoco"] == pins["mujoco-core"]  # MuJoCo 4 refuses a mismatched core


@pytest.mark.skipif(not (ROOT / ".git").exists(), reason="a git checkout")
def test_the_pieces_cannot_be_committed_and_the_page_gives_the_command(payload):
    ignored = subprocess.run(["git", "check-ignore", "-q", ".gpu/payload.part01"], cwd=ROOT)
    assert ignored.returncode == 0  # .gpu/ is ignored: no wheel reaches git by accident
    assert payload.COMMAND in (ROOT / "docs" / "gpu.md").read_text()


def test_the_shipped_results_step_aside_and_come_back(tmp_path, payload):
    """``aside`` moves docs/results (but the GPU records) beside the checkout; ``back`` restores
    every file as it was; a second ``aside`` before ``back`` is refused."""
    mod = payload
    root = tmp_path / "repo"
    for name in ("docs/results/hopper/runs/a.csv", "docs/results/gpu/h.md", "docs/index.md"):
        (root / name).parent.mkdir(parents=True, exist_ok=True)
        (root / name).write_text(name)
    before = sorted(p.relative_to(root).as_posix() for p in root.rglob("*") if p.is_file())
    assert mod.set_aside(root) == ["docs/results/hopper"]
    assert not (root / "docs/results/hopper").exists() and (root / "docs/results/gpu/h.md").exists()
    (mod.aside_dir(root) / "docs/results/extra").mkdir()
    with pytest.raises(SystemExit, match="earlier set-aside"):
        mod.set_aside(root)
    (mod.aside_dir(root) / "docs/results/extra").rmdir()
    assert mod.put_back(root) == ["docs/results/hopper"]
    after = sorted(p.relative_to(root).as_posix() for p in root.rglob("*") if p.is_file())
    assert after == before and (root / "docs/results/hopper/runs/a.csv").read_text().endswith("csv")
    assert not mod.aside_dir(root).exists()
