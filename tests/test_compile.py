"""The update's code paths on a CPU: compiled (``--compile``) and the CUDA-graph path rehearsed
(everything but the capture), against the eager update they must equal.

- compiled vs eager: a whole tiny TD3 run, within ``COMPILED_TOL`` (measured on this project's
  2-core AMD EPYC, torch 2.13: 3e-8 after 300 updates, the fused kernels rounding apart from
  the eager ones), and a compiled run killed and resumed equals it uninterrupted, bit for bit.
- rehearsed vs eager: bit for bit (the same kernels, through static input tensors).
- optimiser state: a checkpoint of either device loads into the other's optimiser.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest
from conftest import e2e_after_first, policy_arrays, stopping_at

torch = pytest.importorskip("torch")

from rrls.agents import Interrupted, TrainConfig, graphs, group, train  # noqa: E402
from rrls.agents.graphs import Update, adam, cache_dir, load_optimizer  # noqa: E402
from rrls.agents.group import COMPILE_MIN_UPDATES, compiles  # noqa: E402
from rrls.agents.loop import train_group  # noqa: E402

COMPILED_TOL = 1e-6  # |compiled - eager| per weight after a 300-update run (measured 3e-8)


def _config(tmp_path, algo, name, seed=1, steps=400, **extra):
    hyper = {"learning_starts": 100, "hidden": (12, 12), "batch_size": 20}
    if algo == "rarl":
        hyper["phase_steps"] = 70
    if algo == "nrmdp":
        hyper["ratio"] = 2
    return TrainConfig(
        algo=algo,
        task="invertedpendulum",
        uncertainty="1d" if algo in ("dr", "m2td3", "sacdr") else None,
        steps=steps,
        seed=seed,
        out=str(tmp_path / name / f"seed{seed}"),
        eval_every=0,
        checkpoint_every=130,
        progress=False,
        hyper=hyper,
        **{"threads": 1, **extra},
    )


def _gap(a, b) -> float:
    x, y = policy_arrays(a), policy_arrays(b)
    assert x.keys() == y.keys() and x
    return max(float(np.abs(x[k] - y[k]).max()) for k in x)


def test_compile_by_default_only_when_the_budget_pays_for_it(tmp_path, monkeypatch):
    long = _config(tmp_path, "td3", "a", steps=100 + COMPILE_MIN_UPDATES)
    assert not compiles(long, 100, 0)  # a CPU: measured no faster compiled
    monkeypatch.setattr(group, "COMPILE_PAYS_ON", ("cpu",))  # as a GPU's default (none here)
    assert compiles(long, 100, 0)
    assert not compiles(long, 100, 101)  # resumed one update short of paying
    assert not compiles(_config(tmp_path, "td3", "b"), 100, 0)  # a test's budget
    assert compiles(_config(tmp_path, "td3", "c", compile=True), 100, 0)
    assert not compiles(_config(tmp_path, "td3", "d", steps=10**6, compile=False), 100, 0)


def test_the_compile_cache_is_the_users_own_unless_set(monkeypatch, tmp_path):
    monkeypatch.setenv("TORCHINDUCTOR_CACHE_DIR", "/tmp/set-by-torch")  # as dynamo does
    monkeypatch.setattr(graphs, "USER_CACHE_DIR", None)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert cache_dir() == tmp_path / "xdg" / "rrls" / "inductor"
    assert os.environ["TORCHINDUCTOR_CACHE_DIR"] == str(tmp_path / "xdg" / "rrls" / "inductor")
    monkeypatch.setattr(graphs, "USER_CACHE_DIR", str(tmp_path / "mine"))
    assert cache_dir() == tmp_path / "mine"
    assert os.environ["TORCHINDUCTOR_CACHE_DIR"] == str(tmp_path / "mine")


@pytest.mark.e2e
def test_a_compiled_run_agrees_with_eager_and_resumes_exactly(tmp_path, monkeypatch):
    compiled_fns = []
    real = torch.compile

    def spy(fn, *args, **kwargs):
        compiled_fns.append(fn)
        return real(fn, *args, **kwargs)

    monkeypatch.setattr(torch, "compile", spy)
    eager = train(_config(tmp_path, "td3", "eager", compile=False))
    assert not compiled_fns
    compiled = train(_config(tmp_path, "td3", "compiled", compile=True))
    assert len(compiled_fns) == 1
    assert graphs.current().compile is False  # restored: a learner made outside stays eager
    expected = graphs.USER_CACHE_DIR or str(Path.home() / ".cache" / "rrls" / "inductor")
    if os.environ.get("XDG_CACHE_HOME") and not graphs.USER_CACHE_DIR:
        expected = str(Path(os.environ["XDG_CACHE_HOME"]) / "rrls" / "inductor")
    assert os.environ["TORCHINDUCTOR_CACHE_DIR"] == expected  # not torch's /tmp default
    assert any(Path(expected).iterdir())
    assert _gap(eager, compiled) <= COMPILED_TOL
    with stopping_at(260), pytest.raises(Interrupted):
        train(_config(tmp_path, "td3", "cut", compile=True))
    resumed = train(_config(tmp_path, "td3", "cut", compile=True), resume=True)
    assert _gap(compiled, resumed) == 0.0


@pytest.mark.slow
@pytest.mark.parametrize("algo", ["td3", "sac", "m2td3", "rarl", "nrmdp"])
def test_compiled_alone_and_in_a_group_and_against_eager(tmp_path, algo):
    eager = train(_config(tmp_path, algo, "eager", compile=False))
    alone = train(_config(tmp_path, algo, "alone", compile=True))
    group = train_group(
        [_config(tmp_path, algo, "group", seed=s, compile=True, threads=2) for s in (0, 1, 2)]
    )
    assert _gap(alone, group[1]) <= 1e-6  # tests/test_group.py's RUN_TOL
    assert _gap(eager, alone) <= COMPILED_TOL


def test_rehearsal_reads_static_inputs_as_a_replayed_graph_would():
    seen = []

    def fn(variant, x):
        seen.append(x["a"])
        return {"y": x["a"] * 2 if variant else x["a"]}

    update = Update(fn, "cpu", rehearse=True)
    assert update.static and not update.graphs
    first = update(True, {"a": torch.ones(3)})
    second = update(True, {"a": torch.full((3,), 4.0)})
    other = update(False, {"a": torch.zeros(2)})
    assert seen[0] is seen[1]  # one static tensor per variant, its values copied in
    assert seen[2] is not seen[0] and seen[2].shape == (2,)
    assert torch.equal(first["y"], torch.full((3,), 2.0))
    assert torch.equal(second["y"], torch.full((3,), 8.0))
    assert torch.equal(other["y"], torch.zeros(2))
    assert not Update(fn, "cpu").static  # the default on a CPU: inputs go straight in


@pytest.mark.e2e
@pytest.mark.parametrize("algo", e2e_after_first(["td3", "sac", "m2td3", "nrmdp"]))
def test_the_rehearsed_cuda_graph_path_trains_and_resumes_as_eager(tmp_path, algo):
    eager = train(_config(tmp_path, algo, "eager", compile=False))
    with graphs.settings(rehearse=True):
        rehearsed = train(_config(tmp_path, algo, "rehearsed", compile=False))
        with stopping_at(260), pytest.raises(Interrupted):
            train(_config(tmp_path, algo, "cut", compile=False))
        resumed = train(_config(tmp_path, algo, "cut", compile=False), resume=True)
    assert not graphs.current().rehearse  # undone after the block
    assert _gap(eager, rehearsed) == 0.0
    assert _gap(eager, resumed) == 0.0


def _stepped(device: str) -> tuple[torch.optim.Adam, list[torch.nn.Parameter]]:
    params = [torch.nn.Parameter(torch.ones(2, 3)), torch.nn.Parameter(torch.zeros(4))]
    opt = adam(params, 1e-3, torch.device(device))
    if device == "cpu":
        for p in params:
            p.grad = torch.ones_like(p)
        opt.step()
    return opt, params


def test_a_gpu_optimisers_checkpoint_steps_on_a_cpu_and_back():
    cpu, _ = _stepped("cpu")
    gpu, gpu_params = _stepped("cuda")  # a GPU's optimiser (its flags; the tensors stay here)
    assert gpu.param_groups[0]["capturable"] and not gpu.param_groups[0]["fused"]
    load_optimizer(gpu, cpu.state_dict())
    assert gpu.param_groups[0]["capturable"] and not gpu.param_groups[0]["fused"]
    step = gpu.state[gpu_params[0]]["step"]
    assert step.dtype == torch.float32 and step.device == gpu_params[0].device and step == 1
    # a checkpoint written by the GPU's optimiser (capturable) steps on a CPU
    state = gpu.state_dict()
    assert state["param_groups"][0]["capturable"]
    resumed, params = _stepped("cpu")
    load_optimizer(resumed, state)
    assert resumed.param_groups[0]["fused"] and not resumed.param_groups[0]["capturable"]
    for p in params:
        p.grad = torch.ones_like(p)
    resumed.step()  # torch.optim refuses a capturable step on a CPU
    assert resumed.state[params[0]]["step"] == 2
    assert state.keys() == cpu.state_dict().keys()
    assert state["state"][0].keys() == cpu.state_dict()["state"][0].keys()
