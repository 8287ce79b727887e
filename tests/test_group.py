"""Many runs in one process: a run's numbers are the same alone and in any group of runs.

``train_group`` stacks K runs (different seeds) into one learner; each keeps its directory,
checkpoint and policy. These tests train tiny runs whose per-run blocks are deliberately not
multiples of the SIMD width (hidden 12, batch 20), alone and in groups, with different thread
counts, killed and resumed mid-episode, and compare the saved numbers bit for bit.
"""

from __future__ import annotations

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from rrls.agents import Interrupted, TrainConfig, train  # noqa: E402
from rrls.agents.loop import train_group  # noqa: E402
from rrls.agents.networks import Actor, TwinCritic  # noqa: E402

ALGOS = ["td3", "dr", "rarl", "nrmdp", "m2td3"]


def _config(tmp_path, algo, seed, name, steps=400, **extra):
    hyper = {"learning_starts": 100, "hidden": (12, 12), "batch_size": 20}
    if algo == "rarl":
        hyper["phase_steps"] = 70  # both players learn before the end
    if algo == "nrmdp":
        hyper["ratio"] = 2
    return TrainConfig(
        algo=algo,
        task="invertedpendulum",
        uncertainty="1d" if algo in ("dr", "m2td3") else None,
        steps=steps,
        seed=seed,
        out=str(tmp_path / name / f"seed{seed}"),
        eval_every=0,
        checkpoint_every=130,  # not at episode ends: the episode in progress is replayed
        progress=False,
        hyper=hyper,
        **extra,
    )


def _arrays(run_dir):
    out = {}
    for name in ("policy.npz", "adversary.npz"):
        if (run_dir / name).exists():
            with np.load(run_dir / name) as f:
                out.update({f"{name}:{k}": f[k] for k in f.files if k != "header"})
    return out


def _same_run(a, b) -> bool:
    x, y = _arrays(a), _arrays(b)
    return x.keys() == y.keys() and all(np.array_equal(x[k], y[k]) for k in x)


@pytest.mark.parametrize("algo", ALGOS)
def test_a_run_is_the_same_alone_and_in_any_group(tmp_path, algo):
    alone = train(_config(tmp_path, algo, 1, "alone", threads=1))
    group = train_group([_config(tmp_path, algo, s, "group", threads=2) for s in (0, 1, 2)])
    swapped = train_group([_config(tmp_path, algo, s, "swapped") for s in (1, 3)])
    assert _same_run(alone, group[1]) and _same_run(alone, swapped[0])
    assert not _same_run(group[0], group[1])  # the seeds do differ
    # the checkpoints agree too: every stacked tensor, replay rows and generators
    a = torch.load(alone / "checkpoint.pt", weights_only=True)
    b = torch.load(group[1] / "checkpoint.pt", weights_only=True)
    assert a["step"] == b["step"] and a["rng"] == b["rng"]
    for name, value in a["learner"]["stacked"].items():
        assert torch.equal(value, b["learner"]["stacked"][name]), name


@pytest.mark.parametrize("algo", ["td3", "m2td3", "rarl"])
def test_a_group_killed_mid_episode_resumes_as_if_never_stopped(tmp_path, algo):
    whole = [train(_config(tmp_path, algo, s, "whole")) for s in (0, 1, 2)]
    # seeds 0 and 1 are killed together at step 260, seed 2 alone at 130
    with pytest.raises(Interrupted):
        train_group([_config(tmp_path, algo, s, "cut", stop_at=260) for s in (0, 1)])
    with pytest.raises(Interrupted):
        train(_config(tmp_path, algo, 2, "cut", stop_at=130))
    # one resume continues all three: seed 2 first catches up, then the runs go on as a group
    seen = []
    cut = train_group(
        [_config(tmp_path, algo, s, "cut") for s in (0, 1, 2)],
        resume=True,
        on_episode=lambda k, step, ret: seen.append(k),
    )
    assert all(_same_run(w, c) for w, c in zip(whole, cut))
    assert set(seen) == {0, 1, 2}
    # a finished group resumed with as many steps is left as it is
    assert train_group([_config(tmp_path, algo, s, "cut") for s in (0, 1, 2)], resume=True)


def test_runs_of_a_group_must_differ_only_in_seed_and_directory(tmp_path):
    a = _config(tmp_path, "td3", 0, "g")
    with pytest.raises(ValueError, match="differ only in seed"):
        train_group([a, _config(tmp_path, "td3", 1, "g", steps=500)])
    with pytest.raises(ValueError, match="one directory each"):
        train_group([a, _config(tmp_path, "td3", 0, "g")])


@torch.no_grad()
@pytest.mark.parametrize("threads", [1, 2])
def test_stacked_layers_give_each_run_the_numbers_it_has_alone(threads):
    # the measured basis of the tests above, at the paper's layer shapes: forward, explicit
    # backward and the input-column gradient of one run equal the same run's in a group
    previous = torch.get_num_threads()
    torch.set_num_threads(threads)
    try:
        for obs_dim, act_dim, batch in ((11, 3, 256), (4, 1, 100), (17, 6, 100)):
            gens = [torch.Generator().manual_seed(s) for s in range(3)]
            group = Actor(obs_dim, act_dim, (256, 256), generators=gens)
            critics = TwinCritic(obs_dim + act_dim, (256, 256), generators=gens)
            single = [torch.Generator().manual_seed(1)]
            alone = Actor(obs_dim, act_dim, (256, 256), generators=single)
            critic = TwinCritic(obs_dim + act_dim, (256, 256), generators=single)
            obs = torch.randn(3, batch, obs_dim)
            a_group, saved_group = group.forward_saved(obs)
            a_alone, saved_alone = alone.forward_saved(obs[1:2])
            assert torch.equal(a_group[1], a_alone[0])
            x = torch.cat((obs, a_group), 2)
            q_group, sq_group = critics.forward_saved(x, n=1)
            q_alone, sq_alone = critic.forward_saved(x[1:2], n=1)
            assert torch.equal(q_group[1], q_alone[0])
            cols = slice(obs_dim, obs_dim + act_dim)
            g_group = critics.backward_saved(sq_group, q_group * 0.01, input_columns=cols)
            g_alone = critic.backward_saved(sq_alone, q_alone * 0.01, input_columns=cols)
            assert torch.equal(g_group[1], g_alone[0])
            grads_group = [torch.zeros_like(p) for p in group.parameters()]
            grads_alone = [torch.zeros_like(p) for p in alone.parameters()]
            group.backward_saved(saved_group, g_group, grads_group)
            alone.backward_saved(saved_alone, g_alone, grads_alone)
            assert all(torch.equal(g[1], h[0]) for g, h in zip(grads_group, grads_alone))
    finally:
        torch.set_num_threads(previous)


@pytest.mark.skipif(not torch.cuda.is_available(), reason="needs a CUDA device")
@pytest.mark.parametrize("algo", ALGOS)
def test_cuda_graphs_replay_what_the_eager_update_computes(tmp_path, algo):
    runs = {}
    for graphs in (False, True):
        configs = [
            _config(tmp_path, algo, s, f"graphs{graphs}", device="cuda", cuda_graphs=graphs)
            for s in (0, 1)
        ]
        runs[graphs] = train_group(configs)
    for eager, graphed in zip(runs[False], runs[True]):
        x, y = _arrays(eager), _arrays(graphed)
        assert x.keys() == y.keys()
        for key in x:  # the same kernels replayed: equal up to the GPU's own nondeterminism
            np.testing.assert_allclose(x[key], y[key], rtol=1e-4, atol=1e-5)


def test_update_runs_the_function_directly_without_a_gpu():
    from rrls.agents.core import Update

    calls = []
    update = Update(lambda variant, x: calls.append((variant, x["a"])) or {"y": x["a"] + 1}, "cpu")
    out = update("v", {"a": torch.ones(2)})
    assert torch.equal(out["y"], torch.full((2,), 2.0)) and calls[0][0] == "v"
    assert not update.graphs  # CUDA graphs only on a CUDA device


@pytest.mark.parametrize("algo", ["nrmdp", "m2td3"])
def test_env_worker_processes_change_no_number(tmp_path, algo):
    # NR-MDP reads its transitions from the envs' infos, M2TD3 resets them with options
    local = train_group([_config(tmp_path, algo, s, "local") for s in (0, 1, 2)])
    spread = train_group([_config(tmp_path, algo, s, "spread", env_workers=2) for s in (0, 1, 2)])
    assert all(_same_run(a, b) for a, b in zip(local, spread))


@pytest.mark.parametrize("algo", ["nrmdp", "m2td3"])
def test_a_group_split_into_several_stacks_changes_no_number(tmp_path, monkeypatch, algo):
    import rrls.agents.loop as loop

    whole = train_group([_config(tmp_path, algo, s, "one") for s in (0, 1, 2)])
    monkeypatch.setattr(loop, "CPU_STACK", 2)  # stacks of 2 and 1, updated in turn
    split = train_group([_config(tmp_path, algo, s, "split") for s in (0, 1, 2)])
    assert all(_same_run(a, b) for a, b in zip(whole, split))
