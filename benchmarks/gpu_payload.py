"""The wheels the GPU machine lacks, carried to it in pieces that fit the ``run`` calls, and the
one command every call runs there (standard library only: it runs before anything is installed).

A call carries at most 64 MiB, the repository's tracked and untracked-not-ignored files
included, and the GPU machine reaches no package index. Its image has Python 3.12, torch with
CUDA, numpy, pandas, SciPy, matplotlib, pyarrow and tensorboard; it lacks MuJoCo, Gymnasium,
warp-lang (a 149 MB wheel) and mujoco-warp. So, here, once per set of versions:

    python3 benchmarks/gpu_payload.py build    # -> .gpu/ (ignored): manifest.json, payload.partNN
    python3 benchmarks/gpu_payload.py aside    # the shipped results beside the checkout
    python3 benchmarks/gpu_payload.py plan     # the calls: carry lists, MiB each, the command

``build`` downloads the pinned wheels for the GPU machine (``WHEELS``, CPython 3.12, manylinux
x86-64), unpacks them into one site folder without what a CUDA run never loads (``DROP``: warp's
CPU compiler, examples and tests), packs it as one tar.xz (86 MiB instead of 162 MiB of
wheels) and cuts it into pieces that fit beside the tree, each with its sha256 in
``manifest.json``. ``plan`` packs the pieces into as few calls as fit and prints them. Every
call runs the same command, only its ``carry`` differs:

    PYTHONUNBUFFERED=1 python3 benchmarks/gpu_payload.py device

``device`` moves each carried piece whose sha256 matches into ``STORE`` (outside the tree: it
stays on the machine while it is warm, between back-to-back calls) and says which are still
missing; once all are in, it checks the whole payload's sha256, unpacks it, and runs
``benchmarks/gpu_runbook.py $OUT`` with what is left of ``--budget`` as its deadline. After the
last call, ``gpu_payload.py back`` puts the shipped results back.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import shutil
import subprocess
import sys
import tarfile
import tempfile
import time
import zipfile
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
GPU_DIR = ROOT / ".gpu"  # ignored (.gitignore): the pieces and their manifest
STORE = Path("/tmp/rrls-gpu")  # on the GPU machine: the pieces in, then the unpacked site
MIB = 1 << 20
LIMIT = 64 * MIB  # what one call may carry, the tree included
MARGIN = 1 * MIB  # for files that appear between the plan and the call
PIECE_MAX = 55 * MIB
#: the versions the twin is tested with (pyproject's ``warp`` extra), for the GPU machine
WHEELS = (
    "warp-lang==1.19.0",
    "mujoco-warp==4.0.0",
    "mujoco==4.0.0",
    "mujoco-core==4.0.0",
    "gymnasium==1.4.0",
    "farama-notifications==0.0.6",
)
#: the GPU machine's Python and platform (the device page's ``pip download`` line)
PIP_TAGS = ["--python-version", "3.12", "--implementation", "cp", "--only-binary=:all:"]
PIP_TAGS += [
    f"--platform={tag}_x86_64"
    for tag in ("manylinux_2_28", "manylinux_2_27", "manylinux_2_17", "manylinux2014", "manylinux1")
]
#: never loaded by a CUDA run: warp's CPU (LLVM) backend, its examples and tests
DROP = ("warp/bin/warp-clang.so", "warp/examples/", "warp/tests/")
#: what every ``run`` call runs (only its ``carry`` differs)
COMMAND = "PYTHONUNBUFFERED=1 python3 benchmarks/gpu_payload.py device"


def sha256(path: Path) -> str:
    digest = hashlib.sha256()
    with path.open("rb") as f:
        for block in iter(lambda: f.read(MIB), b""):
            digest.update(block)
    return digest.hexdigest()


def tree_files(root: Path = ROOT) -> dict[Path, int]:
    """What every call carries anyway, with sizes: tracked and untracked-not-ignored files, and
    shared/."""
    listed = subprocess.run(
        ["git", "ls-files", "-z", "--cached", "--others", "--exclude-standard"],
        cwd=root,
        capture_output=True,
        check=True,
    ).stdout.split(b"\0")
    paths = {root / os.fsdecode(p) for p in listed if p}
    if (root / "shared").is_dir():
        paths |= {p for p in (root / "shared").rglob("*")}
    return {p: p.lstat().st_size for p in paths if p.is_file() and not p.is_symlink()}


def tree_bytes(root: Path = ROOT) -> int:
    return sum(tree_files(root).values())


def biggest(root: Path = ROOT, depth: int = 3, n: int = 3) -> str:
    """The tree's largest folders ``depth`` levels down: what to carry less of."""
    sizes: dict[str, int] = {}
    for path, size in tree_files(root).items():
        folder = "/".join(path.relative_to(root).parts[:depth])
        sizes[folder] = sizes.get(folder, 0) + size
    top = sorted(sizes.items(), key=lambda kv: -kv[1])[:n]
    return ", ".join(f"{name} {size / MIB:.1f} MiB" for name, size in top)


def calls(pieces: list[dict[str, Any]], tree: int, limit: int = LIMIT) -> list[list[str]]:
    """The pieces packed, in order, into as few calls as carry each at most ``limit`` with the
    tree and the manifest; a piece that cannot fit raises."""
    room = limit - tree - MARGIN
    out: list[list[str]] = []
    used = room  # start a new call at the first piece
    for piece in pieces:
        if piece["size"] > room:
            raise ValueError(
                f"{piece['name']} is {piece['size'] / MIB:.1f} MiB but a call has "
                f"{max(room, 0) / MIB:.1f} MiB beside the tree ({tree / MIB:.1f} MiB): "
                "rebuild with a smaller --piece-mib or carry less in the tree (`gpu_payload.py "
                "aside` moves the shipped results beside the checkout)"
            )
        if used + piece["size"] > room:
            out.append([])
            used = 0
        out[-1].append(piece["name"])
        used += piece["size"]
    return out


def download(wheels: Path) -> None:
    """The pinned wheels for the GPU machine (no dependencies: it has the rest)."""
    wheels.mkdir(parents=True, exist_ok=True)
    command = [sys.executable, "-m", "pip", "download", "--no-deps", *PIP_TAGS, "-d", str(wheels)]
    subprocess.run(command + list(WHEELS), check=True)


def pack_site(wheels: list[Path], archive: Path) -> list[str]:
    """Unpack the wheels into one site folder without ``DROP``, then tar.xz it (xz's own
    threads where the command exists). Returns the dropped members."""
    dropped: list[str] = []
    with tempfile.TemporaryDirectory(prefix="rrls-site-") as tmp:
        site = Path(tmp) / "site"
        for wheel in wheels:
            with zipfile.ZipFile(wheel) as z:
                for member in z.namelist():
                    if member.startswith(DROP):
                        dropped.append(member)
                    else:
                        z.extract(member, site)
        if shutil.which("xz"):
            tar = subprocess.Popen(
                ["tar", "-cf", "-", "-C", str(site), "."], stdout=subprocess.PIPE
            )
            with archive.open("wb") as f:
                subprocess.run(["xz", "-6", "-T0", "-c"], stdin=tar.stdout, stdout=f, check=True)
            if tar.wait():
                raise RuntimeError("tar failed")
        else:
            with tarfile.open(archive, "w:xz", preset=6) as t:
                t.add(site, arcname=".")
    return sorted(d for d in dropped if not d.endswith("/"))


def build(args: argparse.Namespace) -> int:
    gpu = args.gpu_dir
    gpu.mkdir(parents=True, exist_ok=True)
    wheels = args.wheels or gpu / "wheels"
    if not args.wheels:
        download(wheels)
    found = sorted(wheels.glob("*.whl"))
    if not found:
        raise SystemExit(f"no wheels in {wheels}")
    piece = int(args.piece_mib * MIB) if args.piece_mib else None
    if args.tree is None:
        args.tree = tree_bytes()
    if piece is None:
        piece = min(PIECE_MAX, LIMIT - args.tree - MARGIN - 64 * 1024)
        if piece < MIB:
            raise SystemExit(f"the tree is {args.tree / MIB:.1f} MiB: under 1 MiB is left a call")
    for old in gpu.glob("payload.part*"):
        old.unlink()
    with tempfile.TemporaryDirectory(prefix="rrls-payload-") as tmp:
        archive = Path(tmp) / "payload.tar.xz"
        dropped = pack_site(found, archive)
        pieces = []
        with archive.open("rb") as f:
            for i, block in enumerate(iter(lambda: f.read(piece), b""), 1):
                part = gpu / f"payload.part{i:02d}"
                part.write_bytes(block)
                pieces.append({"name": part.name, "size": len(block), "sha256": sha256(part)})
        manifest = {
            "python": PIP_TAGS[1],
            "wheels": {w.name: sha256(w) for w in found},
            "dropped": dropped,
            "payload": {"size": archive.stat().st_size, "sha256": sha256(archive)},
            "pieces": pieces,
        }
    (gpu / "manifest.json").write_text(json.dumps(manifest, indent=1) + "\n")
    print(f"{len(pieces)} piece(s), {manifest['payload']['size'] / MIB:.1f} MiB in {gpu}")
    return show_plan(gpu, args.tree)


def show_plan(gpu: Path, tree: int | None = None) -> int:
    """Print the calls: each one's carry list, its MiB with the tree, and the command."""
    manifest = json.loads((gpu / "manifest.json").read_text())
    tree = tree_bytes() if tree is None else tree
    sizes = {p["name"]: p["size"] for p in manifest["pieces"]}
    try:
        plan = calls(manifest["pieces"], tree)
    except ValueError as err:
        print(f"does not fit: {err}; the tree's largest: {biggest()}")
        return 1
    rel = gpu.relative_to(ROOT) if gpu.is_relative_to(ROOT) else gpu
    for i, names in enumerate(plan, 1):
        carry = [str(rel / "manifest.json")] + [str(rel / n) for n in names]
        mib = (tree + sum(sizes[n] for n in names)) / MIB
        last = i == len(plan)
        print(
            f"call {i}/{len(plan)}: carry {json.dumps(carry)} ({mib:.1f} MiB with the "
            f"{tree / MIB:.1f} MiB tree), timeout_s {600 if last else 120}"
            + (": installs, then the runbook" if last else "")
        )
    print(f"command (every call): {COMMAND}")
    return 0


def take_in(gpu: Path, store: Path, manifest: dict[str, Any]) -> list[str]:
    """Move each carried piece with the right sha256 into ``store``; the names still missing."""
    store.mkdir(parents=True, exist_ok=True)
    missing = []
    for p in manifest["pieces"]:
        kept, carried = store / p["name"], gpu / p["name"]
        if kept.exists() and kept.stat().st_size == p["size"]:
            continue
        if carried.exists():
            if sha256(carried) == p["sha256"]:
                shutil.copyfile(carried, kept)
                print(f"{p['name']}: in, sha256 ok", flush=True)
                continue
            print(f"{p['name']}: sha256 differs from the manifest: carry it again", flush=True)
        missing.append(p["name"])
    return missing


def install(store: Path, manifest: dict[str, Any]) -> Path:
    """Join the pieces, check the payload's sha256, unpack it once into ``store/site``."""
    site, done = store / "site", store / "site.sha256"
    want = manifest["payload"]["sha256"]
    if done.exists() and done.read_text().strip() == want:
        return site
    archive = store / "payload.tar.xz"
    with archive.open("wb") as f:
        for p in manifest["pieces"]:
            with (store / p["name"]).open("rb") as part:
                shutil.copyfileobj(part, f)
    if sha256(archive) != want:
        for p in manifest["pieces"]:
            (store / p["name"]).unlink()
        raise SystemExit("the joined payload's sha256 differs from the manifest: carry all again")
    shutil.rmtree(site, ignore_errors=True)
    with tarfile.open(archive, "r:xz") as t:
        t.extractall(site, filter="data")
    archive.unlink()
    done.write_text(want + "\n")
    return site


def device(args: argparse.Namespace) -> int:
    start = time.monotonic()
    path = args.gpu_dir / "manifest.json"
    if not path.exists():
        raise SystemExit(f"no {path}: carry .gpu/manifest.json in every call")
    manifest = json.loads(path.read_text())
    here = f"{sys.version_info.major}.{sys.version_info.minor}"
    if manifest.get("python", here) != here:
        print(f"the wheels are for Python {manifest['python']}, this is {here}", flush=True)
    missing = take_in(args.gpu_dir, args.store, manifest)
    have = len(manifest["pieces"]) - len(missing)
    print(f"{have}/{len(manifest['pieces'])} pieces in {args.store}", flush=True)
    if missing:
        print(f"still to carry: {', '.join(missing)}", flush=True)
        return 0
    site = install(args.store, manifest)
    print(f"installed in {site} after {time.monotonic() - start:.0f} s", flush=True)
    if args.install_only:
        return 0
    out = args.out or Path(os.environ.get("OUT", "gpu-out"))
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    env["PYTHONPATH"] = os.pathsep.join([str(site), str(ROOT), env.get("PYTHONPATH", "")])
    env.pop("MUJOCO_GL", None)  # the machine may have no EGL: rrls sets none either
    deadline = args.budget - (time.monotonic() - start)
    command = [sys.executable, str(ROOT / "benchmarks" / "gpu_runbook.py"), str(out)]
    command += ["--deadline", f"{deadline:.0f}", *args.runbook]
    print(" ".join(command), flush=True)
    return subprocess.run(command, cwd=ROOT, env=env).returncode


#: what the runbook never reads and the tree carries most of: the shipped results (their runs'
#: curves and policies), set beside the checkout for the calls and put back after
ASIDE = ("docs/results",)
#: kept in place: the GPU records the runbook's page links to
KEEP = ("docs/results/gpu",)


def aside_dir(root: Path = ROOT) -> Path:
    return root.parent / f"{root.name}-aside"


def set_aside(root: Path = ROOT) -> list[str]:
    """Move ``ASIDE`` (but ``KEEP``) out of the tree, beside it, so that every call carries
    megabytes less; ``put_back`` undoes it. Refused while an earlier set-aside is not back."""
    target = aside_dir(root)
    if target.exists() and any(target.iterdir()):
        raise SystemExit(f"{target} holds an earlier set-aside: `gpu_payload.py back` first")
    moved = []
    for folder in ASIDE:
        for path in sorted((root / folder).iterdir()) if (root / folder).is_dir() else []:
            name = path.relative_to(root).as_posix()
            if name in KEEP:
                continue
            (target / name).parent.mkdir(parents=True, exist_ok=True)
            shutil.move(str(path), target / name)
            moved.append(name)
    return moved


def put_back(root: Path = ROOT) -> list[str]:
    """Move what ``set_aside`` moved back into the tree, then remove the folder beside it."""
    target = aside_dir(root)
    back = []
    for folder in ASIDE:
        for path in sorted((target / folder).iterdir()) if (target / folder).is_dir() else []:
            name = path.relative_to(target).as_posix()
            if (root / name).exists():
                raise SystemExit(f"{root / name} exists: not overwritten; move it back by hand")
            shutil.move(str(path), root / name)
            back.append(name)
    shutil.rmtree(target, ignore_errors=True)
    return back


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--gpu-dir", type=Path, default=GPU_DIR, help="default: .gpu")
    sub = parser.add_subparsers(dest="verb", required=True)
    b = sub.add_parser("build", help="download, slim, pack and cut the wheels (here)")
    b.add_argument("--wheels", type=Path, help="a folder of wheels already downloaded")
    b.add_argument("--piece-mib", type=float, help="piece size (default: what fits a call)")
    pl = sub.add_parser("plan", help="print the run calls")
    for p in (b, pl):
        p.add_argument("--tree-mib", type=float, help="the tree's size (default: measured)")
    sub.add_parser("aside", help="move the shipped results beside the checkout (before calls)")
    sub.add_parser("back", help="put the shipped results back (after the calls)")
    d = sub.add_parser("device", help="on the GPU machine: take in, install, run the runbook")
    d.add_argument("--store", type=Path, default=STORE)
    d.add_argument("--out", type=Path, help="the runbook's folder (default: $OUT)")
    d.add_argument("--budget", type=float, default=570.0, help="seconds for the whole call")
    d.add_argument("--install-only", action="store_true")
    d.add_argument("runbook", nargs="*", help="more runbook options, after --")
    args = parser.parse_args(argv)
    tree_mib = getattr(args, "tree_mib", None)
    args.tree = None if tree_mib is None else int(tree_mib * MIB)
    if args.verb == "build":
        return build(args)
    if args.verb in ("aside", "back"):
        moved = set_aside() if args.verb == "aside" else put_back()
        where = aside_dir()
        print(f"{args.verb}: {len(moved)} folders ({where}); tree now {tree_bytes() / MIB:.1f} MiB")
        return 0
    if args.verb == "plan":
        return show_plan(args.gpu_dir, args.tree)
    return device(args)


if __name__ == "__main__":
    sys.exit(main())
