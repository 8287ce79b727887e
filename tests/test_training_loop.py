"""The one training loop: options from the dataclasses, NR-MDP/PR-MDP's updates against plain
autograd, saved adversaries, run-directory hygiene and process hygiene."""

from __future__ import annotations

import json

import numpy as np
import pytest
from conftest import stopping_at

torch = pytest.importorskip("torch")

from rrls._progress import PLAIN_LINE  # noqa: E402
from rrls.agents import TrainConfig, hyperparameters, train  # noqa: E402
from rrls.agents.streams import RunSeeds  # noqa: E402
from rrls.cli import main  # noqa: E402

SMALL = ["--hidden", "16", "16", "--batch-size", "32", "--learning-starts", "100"]


def _cli(out, algo, steps=200, *extra):
    return main(
        [
            "train",
            "--algo",
            algo,
            "--task",
            "invertedpendulum",
            "--steps",
            str(steps),
            "--eval-every",
            "0",
            "--checkpoint-every",
            "50",
            "--out",
            str(out),
            *SMALL,
            *extra,
        ]
    )


# -- options come from the dataclasses ------------------------------------------------------------
@pytest.mark.e2e
def test_every_algorithm_option_reaches_its_learner(tmp_path, capsys):
    assert (
        _cli(tmp_path / "pr", "nrmdp", 200, "--mode", "pr", "--alpha", "0.3", "--ratio", "3") == 0
    )
    run = json.loads((tmp_path / "pr" / "run.json").read_text())
    hyper = run["config"]["hyper"]  # the run described once: every resolved hyper-parameter
    assert hyper["mode"] == "pr" and hyper["alpha"] == 0.3
    assert hyper["ratio"] == 3 and run["game"] == "pr"
    assert _cli(tmp_path / "rarl", "rarl", 200, "--phase-steps", "30") == 0
    run = json.loads((tmp_path / "rarl" / "run.json").read_text())
    assert run["config"]["hyper"]["phase_steps"] == 30
    assert run["uncertainty"] == "2d"  # the benchmark's set by default, not the force set
    args = ("--uncertainty", "1d", "--hatomega-learning-rate", "0.01", "--learning-rate", "0.002")
    assert _cli(tmp_path / "m2", "m2td3", 200, *args) == 0
    run = json.loads((tmp_path / "m2" / "run.json").read_text())["config"]["hyper"]
    assert run["hatomega_learning_rate"] == 0.01 and run["learning_rate"] == 0.002
    # and the learner's optimisers use them
    from rrls.agents import algorithm, hyperparameters

    config = TrainConfig(
        algo="m2td3",
        task="invertedpendulum",
        uncertainty="1d",
        hyper={"hatomega_learning_rate": 0.01, "learning_rate": 0.002, "hidden": (4,)},
    )
    hyper = hyperparameters(config)
    env = algorithm("m2td3").make_env(config.task, config.uncertainty, hyper)
    learner = algorithm("m2td3").Learner(env, hyper, [RunSeeds(0)], torch.device("cpu"))
    assert learner.candidates.opt.param_groups[0]["lr"] == 0.01
    opts = (learner.agent.actor_opt, learner.agent.critic_opt)
    assert all(o.param_groups[0]["lr"] == 0.002 for o in opts)
    capsys.readouterr()
    assert _cli(tmp_path / "bad", "td3", 200, "--alpha", "0.2") == 2
    assert "--alpha does not apply to td3 (only to nrmdp)" in capsys.readouterr().err


@pytest.mark.parametrize(
    "option, value",
    [
        ("--steps", "-5"),
        ("--hidden", "0"),
        ("--seed", "-1"),
        ("--learning-rate", "-1"),
        ("--device", "nosuch"),
        ("--alpha", "1.5"),
        ("--threads", "0"),
        ("--uncertainty", "3d"),  # InvertedPendulum has no 3D set
    ],
)
def test_bad_train_options_get_one_line_and_exit_2(tmp_path, capsys, option, value):
    assert _cli(tmp_path / "r", "nrmdp" if option == "--alpha" else "td3", 200, option, value) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("rrls train: ") and "\n" not in err and "Traceback" not in err
    assert not (tmp_path / "r" / "checkpoint.pt").exists()


# -- run directories ---------------------------------------------------------------------------
@pytest.mark.e2e
def test_finished_runs_bad_checkpoints_and_killed_writes(tmp_path, capsys):
    out = tmp_path / "run"
    assert _cli(out, "td3", 200) == 0
    policy = (out / "policy.npz").stat().st_mtime_ns
    capsys.readouterr()
    assert _cli(out, "td3", 200) == 2  # a finished run is never overwritten silently
    assert "finished run" in capsys.readouterr().err
    assert _cli(out, "td3", 200, "--resume") == 0  # nothing left to do
    assert (out / "policy.npz").stat().st_mtime_ns == policy
    assert _cli(out, "td3", 150, "--resume") == 2
    assert "more than --steps 150" in capsys.readouterr().err
    assert _cli(out, "td3", 300, "--resume") == 0  # extends it
    assert json.loads((out / "run.json").read_text())["steps"] == 300
    assert _cli(out, "td3", 200, "--overwrite") == 0
    assert json.loads((out / "run.json").read_text())["steps"] == 200

    cut = tmp_path / "cut"
    with stopping_at(120):
        assert _cli(cut, "td3", 300) == 3
    (cut / ".checkpoint.pt.x1y2.tmp").write_bytes(b"half a checkpoint")  # a killed write
    (cut / "checkpoint.pt").write_bytes(b"")
    capsys.readouterr()
    assert _cli(cut, "td3", 300, "--resume") == 2
    err = capsys.readouterr().err.strip()
    assert str(cut / "checkpoint.pt") in err and "\n" not in err
    (cut / "checkpoint.pt").unlink()
    assert _cli(cut, "td3", 300, "--resume") == 0  # no checkpoint: starts afresh
    assert not list(cut.glob(".*.tmp"))


def test_a_run_leaves_the_process_as_it_found_it(tmp_path):
    from rrls.agents.threads import flush_denormal_enabled

    threads, flush = torch.get_num_threads(), flush_denormal_enabled()
    config = TrainConfig(
        algo="td3",
        task="invertedpendulum",
        steps=150,
        eval_every=0,
        threads=1,
        out=str(tmp_path / "r"),
        progress=False,
        hyper={"learning_starts": 50, "hidden": (8,), "batch_size": 8},
    )
    train(config)
    assert torch.get_num_threads() == threads and flush_denormal_enabled() == flush
    curves = (tmp_path / "r" / "scalars.csv").read_text().splitlines()
    assert curves[0] == "step,metric,value"
    assert any(",charts/episode_return," in line for line in curves[1:])


def test_adaptive_threads_use_idle_cores_and_give_them_back():
    from rrls.agents.threads import AdaptiveThreads

    before = torch.get_num_threads()
    fixed = AdaptiveThreads(1)
    assert torch.get_num_threads() == 1 and fixed.poll() == 1
    fixed.restore()
    auto = AdaptiveThreads(None, interval=0.0)
    assert 1 <= auto.threads <= auto.cores and torch.get_num_threads() == auto.threads
    busy = auto.poll()  # this process's own work never counts as "others"
    assert 1 <= busy <= auto.cores
    auto.restore()
    assert torch.get_num_threads() == before


# -- NR-MDP / PR-MDP (Tessler et al. 2019) ----------------------------------------------------
def _nrmdp_learner(mode: str, alpha: float = 0.3):
    from rrls.agents.algos import nrmdp

    hyper = nrmdp.Config(
        alpha=alpha, mode=mode, hidden=(5,), policy_noise=0.0, batch_size=4, ratio=1, tau=0.5
    )
    env = nrmdp.make_env("invertedpendulum", "2d", hyper)
    return nrmdp.Learner(env, hyper, [RunSeeds(0)], torch.device("cpu")), hyper


def _q1(agent, obs, action):
    return agent.critic(torch.cat([obs, action], 2))[:, 0]


@pytest.mark.parametrize("mode", ["nr", "pr"])
def test_action_robust_target_is_the_references(mode):
    learner, hyper = _nrmdp_learner(mode)
    agent, alpha = learner.agent, hyper.alpha
    g = torch.Generator().manual_seed(0)
    batch = {  # a group of one run: (1, batch, ...)
        "next_obs": torch.randn(1, 4, 4, generator=g),
        "reward": torch.randn(1, 4, generator=g),
        "terminated": torch.tensor([[0.0, 1.0, 0.0, 0.0]]),
    }
    s2 = batch["next_obs"]
    with torch.no_grad():
        mine, theirs = agent.actor_target(s2), learner.opponent_target(s2)

        def q(a):
            return agent.critic_target(torch.cat([s2, a], 2)).amin(1)

        if mode == "nr":  # one critic on the mixed target action
            value = q((1 - alpha) * mine + alpha * theirs)
        else:  # the mixture of the two players' values
            value = (1 - alpha) * q(mine) + alpha * q(theirs)
        expected = batch["reward"] + hyper.gamma * (1 - batch["terminated"]) * value
    zero = torch.zeros(1, 4, 1)  # policy_noise is 0
    torch.testing.assert_close(learner.target(batch, zero, zero), expected)


@pytest.mark.parametrize("mode", ["nr", "pr"])
def test_action_robust_policy_steps_follow_the_reference_objectives(mode):
    # each player's step moves its own actor only, the adversary lowering the protagonist's
    # objective and the protagonist raising it
    learner, hyper = _nrmdp_learner(mode)
    agent, alpha = learner.agent, hyper.alpha
    obs = torch.randn(1, 4, 4, generator=torch.Generator().manual_seed(1))
    for i in range(4):  # a full buffer for the update
        learner.observe(
            obs[:, i].numpy(),
            [(np.zeros(1), np.zeros(1))],
            np.ones(1),
            obs[:, (i + 1) % 4].numpy(),
            np.zeros(1, bool),
            [{"executed_action": np.array([0.1 * i])}],
        )

    @torch.no_grad()
    def objective(adversary_moves: bool):
        a, o, ot = agent, learner.opponent, learner.opponent_target
        if mode == "nr":
            if adversary_moves:
                action = (1 - alpha) * a.actor_target(obs) + alpha * o(obs)
            else:
                action = (1 - alpha) * a.actor(obs) + alpha * ot(obs)
            return _q1(a, obs, action).mean().item()
        if adversary_moves:
            return alpha * _q1(a, obs, o(obs)).mean().item()
        return (1 - alpha) * _q1(a, obs, a.actor(obs)).mean().item()

    for adversary_moves in (True, False):
        moved = learner.opponent if adversary_moves else agent.actor
        still = agent.actor if adversary_moves else learner.opponent
        before = [p.detach().clone() for p in moved.parameters()]
        kept = [p.detach().clone() for p in still.parameters()]
        value = objective(adversary_moves)
        critic = [p.detach().clone() for p in agent.critic.parameters()]
        # the policy step alone (the critic's step is checked by the loss tests)
        if adversary_moves:
            if mode == "nr":
                with torch.no_grad():
                    other = (1 - alpha) * agent.actor_target(obs)
                loss = _q1(agent, obs, other + alpha * learner.opponent(obs)).mean(-1)
            else:
                loss = alpha * _q1(agent, obs, learner.opponent(obs)).mean(-1)
            agent.policy_step(learner.opponent, learner.opponent_opt, loss)
        else:
            if mode == "nr":
                with torch.no_grad():
                    other = alpha * learner.opponent_target(obs)
                loss = -_q1(agent, obs, (1 - alpha) * agent.actor(obs) + other).mean(-1)
            else:
                loss = -(1 - alpha) * _q1(agent, obs, agent.actor(obs)).mean(-1)
            agent.policy_step(agent.actor, agent.actor_opt, loss)
        assert all(torch.equal(p, c) for p, c in zip(agent.critic.parameters(), critic))
        assert not all(torch.equal(p, b) for p, b in zip(moved.parameters(), before))
        assert all(torch.equal(p, k) for p, k in zip(still.parameters(), kept))
        after = objective(adversary_moves)
        assert (after < value) if adversary_moves else (after > value)


def test_the_update_schedule_gives_the_adversary_one_policy_step_in_ratio_plus_one():
    learner, hyper = _nrmdp_learner("nr")  # ratio 1: alternate
    for i in range(4):
        learner.observe(
            np.zeros((1, 4)),
            [None],
            np.ones(1),
            np.ones((1, 4)),
            np.zeros(1, bool),
            [{"executed_action": np.array([0.1 * i])}],
        )
    kinds = [sorted(learner.update(step)) for step in (2, 4, 6, 8)]  # policy_frequency 2
    assert kinds == [
        ["actor_loss", "critic_loss"],
        ["adversary_loss", "critic_loss"],
        ["actor_loss", "critic_loss"],
        ["adversary_loss", "critic_loss"],
    ]
    assert sorted(learner.update(5)) == ["critic_loss"]


# -- adversaries saved, and played against (paper Table 6) ------------------------------------
@pytest.mark.e2e
def test_adversary_is_saved_and_evaluate_dynamic_plays_against_it(tmp_path, capsys):
    from rrls.evaluation import MLPPolicy, evaluate_dynamic, evaluate_run_dynamic

    out = tmp_path / "nr"
    assert _cli(out, "nrmdp", 200, "--alpha", "0.4") == 0
    adversary = MLPPolicy.load(out / "adversary.npz")
    assert adversary.metadata["role"] == "adversary" and adversary.metadata["game"] == "nr"
    assert adversary.metadata["alpha"] == 0.4 and adversary.metadata["task"] == "invertedpendulum"
    result = evaluate_run_dynamic(out, episodes=3, seed=5)
    direct = evaluate_dynamic(
        MLPPolicy.load(out / "policy.npz"),
        adversary,
        "invertedpendulum",
        "nr",
        episodes=3,
        seed=5,
        alpha=0.4,
    )
    assert result.episodes.equals(direct.episodes)
    capsys.readouterr()
    assert main(["evaluate-dynamic", str(out), "--episodes", "3", "--seed", "5"]) == 0
    assert f"{result.mean:.2f} ± {result.std:.2f}" in capsys.readouterr().out

    assert _cli(tmp_path / "rarl", "rarl", 200) == 0
    meta = MLPPolicy.load(tmp_path / "rarl" / "adversary.npz").metadata
    assert meta["game"] == "adversarial" and meta["uncertainty"] == "2d" and meta["act_dim"] == 2
    assert len(evaluate_run_dynamic(tmp_path / "rarl", episodes=2).episodes) == 2
    assert _cli(tmp_path / "td3", "td3", 120) == 0
    assert main(["evaluate-dynamic", str(tmp_path / "td3")]) == 2
    assert "no adversary.npz" in capsys.readouterr().err


def test_hyperparameters_refuse_unknown_names():
    with pytest.raises(ValueError, match="td3 has no hyper-parameter 'alpha'"):
        hyperparameters(TrainConfig(hyper={"alpha": 0.1}))


def test_a_damaged_checkpoint_is_refused_naming_the_file(tmp_path, capsys):
    cut = tmp_path / "cut"
    with stopping_at(120):
        assert _cli(cut, "td3", 300) == 3
    data = bytearray((cut / "checkpoint.pt").read_bytes())
    data[len(data) // 2] ^= 0xFF  # one flipped byte in the middle of the tensors
    (cut / "checkpoint.pt").write_bytes(bytes(data))
    capsys.readouterr()
    assert _cli(cut, "td3", 300, "--resume") == 2
    err = capsys.readouterr().err.strip()
    assert str(cut / "checkpoint.pt") in err and "damaged" in err and "\n" not in err


@pytest.mark.parametrize(
    "algo",
    ["td3", *(pytest.param(a, marks=pytest.mark.e2e) for a in ("dr", "m2td3", "rarl", "nrmdp"))],
)
def test_extending_a_finished_run_equals_the_longer_run(tmp_path, algo):
    # nothing depends on --steps (the replay capacity, RARL's phases, M2TD3's omegas): 200 steps,
    # then --resume --steps 300, equals 300 steps at once (the final checkpoint is at step 200:
    # --checkpoint-every 50), so a reference's budget can be extended run by run
    assert _cli(tmp_path / "long", algo, 300) == 0
    assert _cli(tmp_path / "short", algo, 200) == 0
    assert _cli(tmp_path / "short", algo, 300, "--resume") == 0
    for name in ("policy.npz", "adversary.npz"):
        if (tmp_path / "long" / name).exists() or (tmp_path / "short" / name).exists():
            a, b = (np.load(tmp_path / d / name) for d in ("long", "short"))
            assert a.files == b.files
            assert all(np.array_equal(a[k], b[k]) for k in a.files if k != "header")


def test_a_split_run_trains_on_the_inner_box_only(tmp_path):
    from rrls.agents import algorithm
    from rrls.agents.envs import env_factory
    from rrls.envs import get_uncertainty_set
    from rrls.uncertainty import Split

    box = get_uncertainty_set("hopper", "3d")
    inner = Split.extrapolation(box, 0.5).region
    for algo, attr in (
        ("dr", "uncertainty_set"),
        ("m2td3", "uncertainty_box"),
        ("rarl", "uncertainty_set"),
    ):
        config = TrainConfig(algo=algo, task="hopper", split="extrapolation", out=str(tmp_path))
        env = env_factory(algorithm(algo), config, hyperparameters(config))()
        seen = env.get_wrapper_attr(attr)
        np.testing.assert_allclose(seen.low, inner.low)
        np.testing.assert_allclose(seen.high, inner.high)
        assert config.identity(hyperparameters(config))["split"] == "extrapolation:0.5"
    # DR's draws stay inside the inner box, and reach the physics
    config = TrainConfig(algo="dr", task="hopper", split="extrapolation:0.2", out=str(tmp_path))
    env = env_factory(algorithm("dr"), config, hyperparameters(config))()
    for seed in range(20):
        env.reset(seed=seed)
        point = [env.get_wrapper_attr("get_params")()[n] for n in box.names]
        assert Split.extrapolation(box, 0.2).in_distribution(point)
    assert (
        "-extrapolation0.2-"
        in TrainConfig(algo="td3", task="hopper", split="extrapolation:0.2").out
    )
    assert "split" not in TrainConfig(algo="td3", task="hopper").identity(
        hyperparameters(TrainConfig(algo="td3", task="hopper"))
    )  # runs without a split resume as before
    with pytest.raises(ValueError, match="interpolation's training part is not a box"):
        TrainConfig(algo="dr", task="hopper", split="interpolation")


def test_track_logs_to_weights_and_biases_when_installed(tmp_path, monkeypatch, capsys):
    import sys
    import types

    calls: list[tuple[str, object]] = []

    class FakeRun:
        def log(self, values, step):
            calls.append(("log", (dict(values), step)))

        def finish(self):
            calls.append(("finish", None))

    def init(**kwargs):
        calls.append(("init", kwargs))
        return FakeRun()

    monkeypatch.setitem(sys.modules, "wandb", types.SimpleNamespace(init=init))
    out = tmp_path / "tracked"
    assert _cli(out, "td3", 200, "--eval-every", "100", "--track", "--wandb-project", "p") == 0
    kinds = [k for k, _ in calls]
    assert kinds[0] == "init" and kinds[-1] == "finish" and "log" in kinds
    assert calls[0][1]["project"] == "p" and calls[0][1]["config"]["algo"] == "td3"
    logged = {key for kind, v in calls if kind == "log" for key in v[0]}
    csv = (out / "scalars.csv").read_text().splitlines()[1:]
    assert {line.split(",")[1] for line in csv} <= logged  # every curve reaches W&B too

    def no_login(**kwargs):  # what wandb raises without a login and no tty
        raise RuntimeError("api_key not configured (no-tty). call wandb.login(key=[your_api_key])")

    monkeypatch.setitem(sys.modules, "wandb", types.SimpleNamespace(init=no_login))
    capsys.readouterr()
    assert _cli(tmp_path / "nologin", "td3", 50, "--track") == 2
    lines = capsys.readouterr().err.strip().splitlines()
    err = "\n".join(line for line in lines if not PLAIN_LINE.match(line))  # progress aside
    assert len(err.splitlines()) == 1 and "wandb login" in err and "WANDB_MODE=offline" in err
    assert "api_key not configured" in err
    monkeypatch.setitem(sys.modules, "wandb", None)  # not installed: one line naming the fix
    with pytest.raises(ValueError, match="pip install wandb"):
        train(
            TrainConfig(
                algo="td3", task="invertedpendulum", steps=10, track=True, out=str(tmp_path / "x")
            )
        )


def test_the_stop_hook_is_an_environment_variable_not_an_option():
    from conftest import STOP_AT_ENV as used_by_the_tests

    from rrls.agents.run import STOP_AT_ENV

    assert STOP_AT_ENV == used_by_the_tests
    assert "stop_at" not in TrainConfig.__dataclass_fields__
    assert main(["train", "--stop-at", "5"]) == 2  # no such option any more


def test_run_json_lists_every_execution_with_its_machine(tmp_path, monkeypatch, capsys):
    """A run resumed on another machine says so: ``provenance.executions`` lists each process
    with the step it started from and its machine; a checkpoint written before executions were
    recorded resumes with its first execution's machine unknown."""
    import io

    from rrls import files
    from rrls.agents import run as run_module

    def on(cpu):
        monkeypatch.setattr(run_module, "machine", lambda: {"cpu": cpu, "simd": "X86_V3"})

    out = tmp_path / "cut"
    on("first")
    with stopping_at(120):
        assert _cli(out, "td3", 300) == 3
    on("second")
    assert _cli(out, "td3", 300, "--resume") == 0
    provenance = json.loads((out / "run.json").read_text())["provenance"]
    executions = provenance["executions"]
    assert [e["first_step"] for e in executions] == [0, 150]  # its checkpoint: every 50 steps
    assert [e["machine"]["cpu"] for e in executions] == ["first", "second"]
    assert provenance["machine"] == executions[-1]["machine"]  # the last one's, as before

    whole = tmp_path / "whole"
    assert _cli(whole, "td3", 200) == 0
    executions = json.loads((whole / "run.json").read_text())["provenance"]["executions"]
    assert [(e["first_step"], e["machine"]["cpu"]) for e in executions] == [(0, "second")]

    old = tmp_path / "old"
    with stopping_at(120):
        assert _cli(old, "td3", 300) == 3
    state = torch.load(old / "checkpoint.pt", weights_only=True)

    def rewrite(**changed):
        buffer = io.BytesIO()
        torch.save({**state, **changed}, buffer)
        files.write_sealed(old / "checkpoint.pt", buffer.getvalue())

    rewrite(**{run_module.EXECUTIONS_KEY: '{"first_step": 0}'})  # not a list: refused
    capsys.readouterr()
    assert _cli(old, "td3", 300, "--resume") == 2
    lines = capsys.readouterr().err.strip().splitlines()
    err = "\n".join(line for line in lines if not PLAIN_LINE.match(line))  # progress aside
    assert "its executions are not a list" in err and "\n" not in err
    del state[run_module.EXECUTIONS_KEY]  # as an earlier rrls wrote it
    rewrite()
    assert _cli(old, "td3", 300, "--resume") == 0
    executions = json.loads((old / "run.json").read_text())["provenance"]["executions"]
    assert [(e["first_step"], e["machine"]) for e in executions][0] == (0, None)
    assert [e["first_step"] for e in executions] == [0, 150]
