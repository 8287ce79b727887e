"""Every algorithm's training, byte for byte as recorded: what one run (and one group) writes
after a warm-up, checkpoints, a periodic evaluation and a loss log inside the run.

Recorded from the training code as it stood before its cadence (warm-up, episode ends, loss
logs, periodic evaluations, checkpoints, finish) moved into one driver, so the move is shown to
change no number: the last checkpoint (learner state, the loop's generator, the episode in
progress, the config), the exported policies, the curves of ``scalars.csv`` (without the wall
clock's ``steps_per_second``) and the losses logged to TensorBoard.

Float32 training is not the same bits on every CPU kernel (ATen's scalar kernels, another torch
or warp; another CPU maker, whose MKL paths may differ: not measured): unlike the ``exactness``
tests, whose results must not depend on the kernels, these digests are recorded per (torch
version, CPU maker) with the ATen capabilities they were measured under, and the test is
skipped (saying so) elsewhere. Record a set for another machine from a commit known to be right
with ``RRLS_RECORD_IDENTITY=1 python3 -m pytest tests/test_driver_identity.py -s`` (it prints
the table instead of comparing).
"""

from __future__ import annotations

import hashlib
import io
import os
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from conftest import policy_arrays

torch = pytest.importorskip("torch")

from rrls import files, rundir  # noqa: E402
from rrls.agents import TrainConfig, train  # noqa: E402
from rrls.agents.loop import train_group  # noqa: E402
from rrls.agents.run import EXECUTIONS_KEY  # noqa: E402

pytestmark = pytest.mark.e2e  # training runs: minutes on a small CPU

ALGOS = ["td3", "dr", "rarl", "nrmdp", "m2td3", "sac", "sacdr"]
STEPS = 1000  # the losses are logged every 1 000 steps: one log, at the end
TWIN_STEPS = 200  # the twin on warp's CPU device is slow: no loss log (the same driver logs)
RECORD = os.environ.get("RRLS_RECORD_IDENTITY") == "1"

#: (torch version, CPU maker) -> case -> digest of what the run wrote; recorded on AMD EPYC
#: (AVX2), torch 2.13.0 (CPU) and warp 1.19.0, from commit 4adf611 (before the driver)
RECORDED: dict[tuple[str, str], dict[str, str]] = {
    ("2.13.0+cpu", "AuthenticAMD"): {
        "td3": "66a3302afc64ce85",
        "dr": "ee85101ce6e32b26",
        "rarl": "cfd0af6c2fcdcc3b",
        "nrmdp": "377e1ea689ee2d8d",
        "m2td3": "1e231447dbe8fbbb",
        "sac": "968a3a854f97fcdc",
        "sacdr": "24745e6ebf62cb4f",
        "td3 group": "21beb8d2e48a70c1/69296b44ea04fec6",
        "m2td3 group": "4d2f04dc6ccb9e4d/404b566cd5ef7737",
    },
    ("2.13.0+cpu warp 1.19.0", "AuthenticAMD"): {
        "td3 twin": "266f79651e1c651c/e47df796e989d578",
        # recorded anew when M2TD3 moved into the resident blocks (its points on the device)
        "m2td3 twin": "5dff2cecfbf2a92e/e28ce9c096e3b49d",
        "sac train_on_twin": "f89319f178100305",
    },
}


#: the ATen capabilities the digests were measured under: the same bits with AVX2 and with
#: AVX-512 kernels (an AMD EPYC with AVX-512 gave every digest above), other bits with ATen's
#: scalar ones (``ATEN_CPU_CAPABILITY=default``)
CAPABILITIES = ("AVX2", "AVX512")


def _maker() -> str:
    """The CPU's maker (``vendor_id``: AuthenticAMD, GenuineIntel), "" where not said."""
    try:
        lines = Path("/proc/cpuinfo").read_text().splitlines()
    except OSError:
        return ""
    return next((ln.split(":", 1)[1].strip() for ln in lines if ln.startswith("vendor_id")), "")


def _kernels() -> tuple[str, str]:
    return torch.__version__, _maker()


def _config(
    tmp_path: Path, algo: str, seed: int, name: str, steps: int = STEPS, **extra: Any
) -> TrainConfig:
    hyper: dict[str, Any] = {"learning_starts": 60, "hidden": (8, 8), "batch_size": 16}
    if algo == "rarl":
        hyper["phase_steps"] = 70  # both players learn before the end
    if algo == "nrmdp":
        hyper["ratio"] = 2
    return TrainConfig(
        algo=algo,
        task="invertedpendulum",
        uncertainty="1d" if algo in ("dr", "m2td3", "sacdr") else None,
        steps=steps,
        seed=seed,
        out=str(tmp_path / name / f"seed{seed}"),
        eval_every=steps * 9 // 20,  # evaluations at 450 and 900 (of 1 000)
        eval_episodes=1,
        checkpoint_every=steps // 3,  # the last at 999, mid-episode: its episode is kept
        threads=1,
        progress=False,
        hyper=hyper,
        **extra,
    )


def _feed(h: Any, value: Any) -> None:
    """A canonical byte stream of a checkpoint's nested contents."""
    if isinstance(value, dict):
        for key in sorted(value):
            h.update(f"<{key}>".encode())
            _feed(h, value[key])
    elif isinstance(value, (list, tuple)):
        h.update(f"[{len(value)}".encode())
        for item in value:
            _feed(h, item)
    elif isinstance(value, torch.Tensor):
        t = value.detach().cpu().contiguous()
        h.update(f"{t.dtype}{tuple(t.shape)}".encode())
        h.update(t.numpy().tobytes() if t.dtype != torch.bfloat16 else t.float().numpy().tobytes())
    else:
        h.update(repr(value).encode())


def _losses(run: Path) -> list[tuple[str, int, float]]:
    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

    events = EventAccumulator(str(run / rundir.TENSORBOARD), size_guidance={"scalars": 0})
    events.Reload()
    tags = sorted(t for t in events.Tags()["scalars"] if t.startswith("losses/"))
    return [(t, e.step, e.value) for t in tags for e in events.Scalars(t)]


def _digest(run: Path, steps: int = STEPS) -> str:
    """What a finished run wrote, as one digest (the wall clock left out)."""
    h = hashlib.sha256()
    checkpoint = torch.load(
        io.BytesIO(files.read_sealed(run / rundir.CHECKPOINT)), weights_only=True
    )
    assert checkpoint["step"] == steps // 3 * 3
    # the executions record where and from which commit it ran (provenance, not training)
    assert checkpoint.pop(EXECUTIONS_KEY)
    _feed(h, checkpoint)
    for name, array in sorted(policy_arrays(run).items()):
        h.update(name.encode() + np.ascontiguousarray(array).tobytes())
    rows = (run / rundir.SCALARS).read_text().splitlines()
    curves = [r for r in rows if ",charts/steps_per_second," not in r]
    assert any(",eval/nominal_return," in r for r in curves)
    assert any(",charts/episode_return," in r for r in curves)
    h.update("\n".join(curves).encode())
    losses = _losses(run)
    assert {step for _, step, _ in losses} == ({STEPS} if steps >= STEPS else set())
    h.update(repr(losses).encode())
    return h.hexdigest()[:16]


def _check(case: str, digests: list[str], kernels: tuple[str, str] | None = None) -> None:
    kernels = kernels or _kernels()
    got = "/".join(digests)
    if RECORD:
        print(f'RECORDED {kernels} "{case}": "{got}",')
        return
    recorded = RECORDED.get(kernels)
    capability = torch.backends.cpu.get_cpu_capability()
    if recorded is None or capability not in CAPABILITIES:
        where = f"torch {kernels[0]} on {kernels[1] or 'this CPU'} ({capability} kernels)"
        pytest.skip(f"no training digests recorded for {where}")
    assert got == recorded[case]


@pytest.mark.parametrize("algo", ALGOS)
def test_a_run_writes_what_it_wrote_before(tmp_path: Path, algo: str) -> None:
    run = train(_config(tmp_path, algo, 0, "alone"))
    _check(f"{algo}", [_digest(run)])


@pytest.mark.parametrize("algo", ["td3", "m2td3"])
def test_a_group_writes_what_it_wrote_before(tmp_path: Path, algo: str) -> None:
    runs = train_group([_config(tmp_path, algo, s, "group") for s in (1, 2)])
    _check(f"{algo} group", [_digest(run) for run in runs])


#: the twin's cases: warp's CPU device, its kernels compiled by this warp
def _twin_kernels() -> tuple[str, str]:
    import warp as wp

    return f"{torch.__version__} warp {wp.config.version}", _maker()


@pytest.mark.warp
@pytest.mark.parametrize("algo", ["td3", "m2td3"])
def test_a_twin_run_writes_what_it_wrote_before(tmp_path: Path, algo: str) -> None:
    """TD3 and M2TD3 in the twin's device-resident blocks (M2TD3's points chosen on the device
    since it trains there; before, through each run's CPU env: recorded anew then)."""
    pytest.importorskip("mujoco_warp")
    twin = {"simulator": "warp", "device": "cpu"}
    runs = train_group([_config(tmp_path, algo, s, "twin", TWIN_STEPS, **twin) for s in (1, 2)])
    _check(f"{algo} twin", [_digest(run, TWIN_STEPS) for run in runs], _twin_kernels())


@pytest.mark.warp
def test_the_twin_library_loop_gives_what_it_gave_before() -> None:
    """``train_on_twin``: the policies and the episode returns, without run directories."""
    pytest.importorskip("mujoco_warp")
    from rrls.agents.on_twin import train_on_twin

    hyper = {"learning_starts": 20, "batch_size": 16, "hidden": (8, 8)}
    out = train_on_twin("sac", "invertedpendulum", (0, 1), 80, device="cpu", hyper=hyper, block=16)
    h = hashlib.sha256(repr(out.returns).encode())
    obs = np.random.default_rng(0).normal(size=(5, 4))
    for policy in out.policies:
        h.update(np.ascontiguousarray(policy(obs)).tobytes())
    assert out.steps == 80 and sum(map(len, out.returns)) > 0
    _check("sac train_on_twin", [h.hexdigest()[:16]], _twin_kernels())
