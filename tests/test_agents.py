"""Baselines: TD3's losses by hand, time limits, exact resume, M2TD3's candidates, the CLI (the
slow learning checks: ``test_learning.py``)."""

from __future__ import annotations

import json

import numpy as np
import pytest
from conftest import e2e_after_first, stopping_at

torch = pytest.importorskip("torch")

from rrls.agents import TrainConfig, hyperparameters, train  # noqa: E402
from rrls.agents.algos.m2td3 import Candidates  # noqa: E402
from rrls.agents.algos.td3 import TD3, TD3Config  # noqa: E402
from rrls.agents.streams import NumpyGenerators, RunSeeds  # noqa: E402
from rrls.cli import main  # noqa: E402

ALGOS = ["td3", "dr", "rarl", "nrmdp", "m2td3", "sac", "sacdr"]
RANDOMISED = ("dr", "m2td3", "sacdr")


def flat(state, prefix=""):
    """A nested checkpoint state as {dotted name: value}."""
    if isinstance(state, dict):
        return {k: v for key, sub in state.items() for k, v in flat(sub, f"{prefix}{key}.").items()}
    if isinstance(state, list | tuple):
        return {k: v for i, sub in enumerate(state) for k, v in flat(sub, f"{prefix}{i}.").items()}
    return {prefix[:-1]: state}


SMALL = ["--hidden", "16", "16", "--batch-size", "32"]


def _cli_train(out, algo, steps=300, extra=()):
    return main(
        [
            "train",
            "--algo",
            algo,
            "--task",
            "invertedpendulum",
            "--steps",
            str(steps),
            "--learning-starts",
            "100",
            "--eval-every",
            "150",
            "--seed",
            "1",
            "--out",
            str(out),
            "--checkpoint-every",
            "50",
            *SMALL,
            *extra,
        ]
    )


def _checkpoint(run_dir):
    from rrls.agents.run import read_checkpoint
    from rrls.rundir import CHECKPOINT

    return read_checkpoint(run_dir / CHECKPOINT)


@pytest.mark.parametrize("algo", e2e_after_first(ALGOS))
def test_every_algorithm_trains_through_the_cli(tmp_path, algo, capsys):
    out = tmp_path / algo
    uncertainty = ["--uncertainty", "1d"] if algo in RANDOMISED else []
    lr = ["--policy-lr", "0.002"] if algo.startswith("sac") else ["--learning-rate", "0.002"]
    assert _cli_train(out, algo, extra=[*uncertainty, *lr]) == 0
    state = flat(_checkpoint(out)["learner"])
    # one run's slice (a group of one) of every tensor: its actor's first layer is (1, in, out)
    actors = [n for n in state if "actor" in n and n.endswith("0.weight") and "opt" not in n]
    assert actors and all(state[n].shape == (1, 4, 16) for n in actors)
    meta = json.loads((out / "run.json").read_text())
    assert meta["algorithm"] == algo and meta["task"] == "invertedpendulum"
    assert meta["steps"] == 300 and meta["obs_dim"] == 4 and meta["act_dim"] == 1
    assert {"torch", "rrls", "mujoco"} <= set(meta["versions"])
    assert list((out / "tb").glob("events.out.tfevents.*"))
    # the run directory is a policy for `rrls evaluate` (the task comes from its metadata)
    capsys.readouterr()
    assert (
        main(
            [
                "evaluate",
                str(out),
                "--uncertainty",
                "1d",
                "--mesh",
                "2",
                "--episodes",
                "1",
                "--workers",
                "1",
                "--out",
                str(tmp_path / "eval"),
            ]
        )
        == 0
    )
    assert "worst case" in capsys.readouterr().out


@pytest.mark.parametrize("algo", e2e_after_first(ALGOS))
def test_killed_and_resumed_run_ends_bit_identical(tmp_path, algo):
    extra = ["--uncertainty", "1d"] if algo in RANDOMISED else []
    extra += ["--phase-steps", "70"] if algo == "rarl" else []  # both phases before the cut
    extra += ["--ratio", "2"] if algo == "nrmdp" else []
    assert _cli_train(tmp_path / "whole", algo, steps=400, extra=extra) == 0
    with stopping_at(220):
        assert _cli_train(tmp_path / "cut", algo, steps=400, extra=extra) == 3
    assert _cli_train(tmp_path / "cut", algo, steps=400, extra=extra) == 2  # needs --resume
    assert _cli_train(tmp_path / "cut", algo, steps=400, extra=[*extra, "--resume"]) == 0
    whole, cut = _checkpoint(tmp_path / "whole"), _checkpoint(tmp_path / "cut")
    assert whole["step"] == cut["step"] and whole["warmup"] == cut["warmup"]
    # every network, target, optimiser moment, generator, replay row (and M2TD3's candidates)
    sa, sb = flat(whole["learner"]), flat(cut["learner"])
    assert sa.keys() == sb.keys()
    for key, value in sa.items():
        same = torch.equal(value, sb[key]) if isinstance(value, torch.Tensor) else value == sb[key]
        assert same, key
    a, b = (np.load(d / "policy.npz") for d in (tmp_path / "whole", tmp_path / "cut"))
    assert all(np.array_equal(a[k], b[k]) for k in a.files if k != "header")
    if algo in ("rarl", "nrmdp"):  # the saved adversaries are equal too
        adversaries = [np.load(d / "adversary.npz") for d in (tmp_path / "whole", tmp_path / "cut")]
        weights = [k for k in adversaries[0].files if k != "header"]  # the header names the dir
        assert all(np.array_equal(adversaries[0][k], adversaries[1][k]) for k in weights)
    assert json.loads((tmp_path / "whole" / "run.json").read_text())["steps"] == 400


def test_normalize_omega_changes_what_the_m2td3_critics_see(tmp_path):
    extra = ["--uncertainty", "1d"]
    assert _cli_train(tmp_path / "raw", "m2td3", steps=250, extra=extra) == 0
    assert (
        _cli_train(tmp_path / "unit", "m2td3", steps=250, extra=[*extra, "--normalize-omega"]) == 0
    )
    raw, unit = (flat(_checkpoint(tmp_path / d)["learner"]) for d in ("raw", "unit"))
    # same seed, same data until learning starts: only the critics' input scale differs
    key = "agent.critic.layers.0.weight"
    assert torch.isfinite(unit[key]).all() and not torch.equal(raw[key], unit[key])


def test_bad_learning_rate_is_refused():
    for lr in (0.0, -1e-3, float("nan")):
        with pytest.raises(ValueError, match="learning_rate"):
            hyperparameters(TrainConfig(hyper={"learning_rate": lr}))


def test_resume_refuses_another_configuration(tmp_path):
    with stopping_at(150):
        assert _cli_train(tmp_path / "r", "td3", steps=200) == 3
    with pytest.raises(ValueError, match="seed"):
        train(
            TrainConfig(
                algo="td3",
                task="invertedpendulum",
                uncertainty="2d",
                steps=200,
                seed=2,
                out=str(tmp_path / "r"),
                progress=False,
                hyper={"learning_starts": 100, "hidden": (16, 16), "batch_size": 32},
            ),
            resume=True,
        )


# -- TD3's losses against hand computations -------------------------------------------------------
# The networks hold a group of runs: tensors are (K, batch, ...); these use a group of one.
def _tiny() -> TD3:
    cfg = TD3Config(hidden=(3,), policy_noise=0.0, gamma=0.9, tau=0.25)
    return TD3(2, np.array([-2.0]), np.array([2.0]), cfg, [RunSeeds(0)], torch.device("cpu"))


def _mlp(x, layers, out_act=None):
    for i, layer in enumerate(layers):
        x = x @ layer.weight[0] + layer.bias[0, 0]
        if i < len(layers) - 1:
            x = torch.relu(x)
    return out_act(x) if out_act else x


def _critic(crit, x, i):
    """Critic ``i`` of run 0, by hand."""
    out = x
    for j, layer in enumerate(crit.layers):
        out = out @ layer.weight[0, i] + layer.bias[0, i, 0]
        if j < len(crit.layers) - 1:
            out = torch.relu(out)
    return out.squeeze(-1)


def test_td_target_matches_the_formula_by_hand():
    agent = _tiny()
    next_obs = torch.tensor([[0.5, -1.0], [2.0, 0.3]])
    reward, terminated = torch.tensor([1.0, -0.5]), torch.tensor([0.0, 1.0])
    data = {"next_obs": next_obs[None], "reward": reward[None], "terminated": terminated[None]}
    y = agent.td_target(data, torch.zeros(1, 2, 1))[0]
    a = 2.0 * _mlp(next_obs, agent.actor_target.layers, torch.tanh)
    x = torch.cat([next_obs, a], 1)
    q = [_critic(agent.critic_target, x, i) for i in range(2)]
    expected = reward + 0.9 * (1 - terminated) * torch.minimum(q[0], q[1])
    torch.testing.assert_close(y, expected)
    assert y[1] == -0.5  # terminated: no bootstrap


def test_critic_loss_actor_loss_and_polyak_by_hand():
    agent = _tiny()
    obs, action = torch.tensor([[0.1, 0.2], [0.3, -0.4]]), torch.tensor([[0.5], [-1.0]])
    target = torch.tensor([1.0, 2.0])
    x = torch.cat([obs, action], 1)
    with torch.no_grad():
        q = [_critic(agent.critic, x, i) for i in range(2)]
    expected = ((q[0] - target) ** 2).mean() + ((q[1] - target) ** 2).mean()
    before = [p.detach().clone() for p in agent.critic_target.parameters()]
    loss = agent.critic_step(obs[None], action[None], target[None])
    torch.testing.assert_close(loss, expected[None])
    with torch.no_grad():
        a = agent.actor(obs[None])[0]
        q1 = _critic(agent.critic, torch.cat([obs, a], 1), 0)
    critic_before = [p.detach().clone() for p in agent.critic.parameters()]
    torch.testing.assert_close(agent.actor_step(obs[None]), -q1.mean()[None])
    # the actor step leaves the critic untouched
    assert all(torch.equal(p, c) for p, c in zip(agent.critic.parameters(), critic_before))
    agent.soft_update()
    for old, new, src in zip(before, agent.critic_target.parameters(), agent.critic.parameters()):
        torch.testing.assert_close(new, 0.75 * old + 0.25 * src)


def test_replay_batches_keep_each_transition_together_and_survive_a_checkpoint():
    from rrls.agents.replay import ReplayBuffer, transition_fields

    fields = transition_fields(3, (2, 2), omega=(1,))
    seeds = [RunSeeds(5), RunSeeds(6)]
    buffer = ReplayBuffer(8, fields, "cpu", seeds)  # two runs: run 1 stores the negated values
    for i in range(11):  # wraps around: transitions 3..10 remain
        sign = np.array([1.0, -1.0])
        buffer.add(
            obs=sign[:, None] * np.full(3, i),
            action=sign[:, None, None] * np.full((2, 2), -i),
            reward=sign * 10.0 * i,
            next_obs=sign[:, None] * np.full(3, i + 1),
            terminated=np.full(2, float(i % 2)),
            omega=sign[:, None] * np.array([0.5 * i]),
        )
    assert len(buffer) == 8
    batch = buffer.gather(buffer.draw(64))
    assert batch["action"].shape == (2, 64, 2, 2) and batch["reward"].shape == (2, 64)
    for k, sign in enumerate((1.0, -1.0)):
        i = sign * batch["obs"][k, :, 0]
        assert set(i.tolist()) <= set(range(3, 11))
        torch.testing.assert_close(sign * batch["action"][k], -i.view(-1, 1, 1).expand(-1, 2, 2))
        torch.testing.assert_close(sign * batch["reward"][k], 10 * i)
        torch.testing.assert_close(sign * batch["next_obs"][k], (i + 1).view(-1, 1).expand(-1, 3))
        torch.testing.assert_close(batch["terminated"][k], i % 2)
        torch.testing.assert_close(sign * batch["omega"][k, :, 0], 0.5 * i)
    # each run samples from its own generator: the two runs' batches differ
    assert not torch.equal(batch["obs"][0, :, 0], -batch["obs"][1, :, 0])

    restored = ReplayBuffer(8, fields, "cpu", [RunSeeds(0), RunSeeds(0)])
    restored.load_state_dict(buffer.state_dict())
    expected, got = buffer.gather(buffer.draw(16)), restored.gather(restored.draw(16))
    for name, values in expected.items():
        torch.testing.assert_close(got[name], values)


def test_truncation_bootstraps_and_no_transition_crosses_a_reset(tmp_path):
    # HalfCheetah never terminates: 10-step episodes end by truncation only
    config = TrainConfig(
        algo="td3",
        task="halfcheetah",
        steps=30,
        eval_every=0,
        out=str(tmp_path),
        checkpoint_every=1,
        max_episode_steps=10,
        progress=False,
        hyper={"learning_starts": 100, "hidden": (8,), "batch_size": 8},
    )
    train(config)
    learner = _checkpoint(tmp_path)["learner"]
    table = learner["buffer"]["table"][0]  # obs 17, action 6, reward, next_obs 17, terminated
    obs, next_obs, terminated = table[:, :17], table[:, 24:41], table[:, 41]
    assert len(table) == 30 and not terminated.any()
    for i in range(29):
        same = torch.equal(next_obs[i], obs[i + 1])
        assert same == (i not in (9, 19))  # after a reset the next obs is a new initial state
    # InvertedPendulum under random actions falls: those transitions are terminal
    config = TrainConfig(
        algo="td3",
        task="invertedpendulum",
        uncertainty="2d",
        steps=60,
        eval_every=0,
        out=str(tmp_path / "ip"),
        checkpoint_every=1,
        progress=False,
        hyper={"learning_starts": 100, "hidden": (8,), "batch_size": 8},
    )
    train(config)
    state = _checkpoint(tmp_path / "ip")
    term = state["learner"]["buffer"]["table"][0, :, -1]
    # the checkpoint is taken at step 60, possibly mid-episode
    assert term.sum() == state["episodes"]
    assert term[-1] == 1 or len(state["episode"]["actions"][0]) > 0


# -- M2TD3's candidates --------------------------------------------------------------------------
def _candidates(low, high, seed=0):
    from rrls.agents.algos.m2td3 import Config

    rngs = NumpyGenerators([RunSeeds(seed)], "algo")
    return Candidates(low, high, rngs, Config(), torch.device("cpu")), rngs[0]


def _values(cands):
    with torch.no_grad():
        return cands.values()[0].numpy()


def test_candidates_stay_in_the_box_and_restart_by_the_rules():
    low, high = np.array([0.1, 1.0]), np.array([3.0, 11.0])
    cands, rng = _candidates(low, high)
    values = _values(cands)
    assert ((values >= low) & (values <= high)).all()
    for _ in range(300):  # push every candidate hard towards +infinity
        for k in range(cands.n):
            cands.step(-1e3 * cands.values()[0, k].sum()[None], torch.tensor([k]))
    moved = _values(cands)
    assert ((moved >= low) & (moved <= high)).all() and (moved > values).all()

    # two candidates within L1 distance 0.1: the first of the pair is re-initialised
    with torch.no_grad():
        cands.logits[2].copy_(cands.logits[4])
    cands.probabilities[0] = torch.tensor([0.3, 0.1, 0.2, 0.2, 0.2], dtype=torch.float64)
    kept = _values(cands)
    assert cands.restart(0, rng) == [2]
    after = _values(cands)
    assert not np.allclose(after[2], kept[2]) and np.allclose(
        np.delete(after, 2, 0), np.delete(kept, 2, 0)
    )
    assert float(cands.probabilities[0, 2]) == pytest.approx((0.3 + 0.1 + 0.2 + 0.2) / 4)
    assert cands.logits[2] not in cands.opt.state  # a fresh Adam with the fresh point

    # a candidate whose probability fell below 0.05 is re-initialised too
    cands.probabilities[0] = torch.tensor([0.5, 0.02, 0.18, 0.1, 0.2], dtype=torch.float64)
    assert 1 in cands.restart(0, rng)
    assert float(cands.probabilities[0, 1]) == pytest.approx((0.5 + 0.18 + 0.1 + 0.2) / 4)

    # the worst candidate's probability moves by 1/L towards 1
    cands.probabilities[0] = 0.2
    cands.mark_worst(torch.tensor([3]), torch.tensor([1 / 10], dtype=torch.float64))
    np.testing.assert_allclose(cands.probabilities[0], [0.18, 0.18, 0.18, 0.28, 0.18])


def test_each_candidate_has_its_own_adam_and_only_the_chosen_one_steps():
    from rrls.agents.algos.m2td3 import Config

    cands, _ = _candidates(np.zeros(2), np.ones(2), seed=1)
    logit = torch.nn.Parameter(cands.logits[3].detach().clone())
    reference = torch.optim.Adam([logit], lr=Config().hatomega_learning_rate)
    others = [p.detach().clone() for i, p in enumerate(cands.logits) if i != 3]
    for i in range(4):
        weights = torch.tensor([0.5 - i, 2.0 * i + 1])
        cands.step((cands.values()[0, 3] * weights).sum()[None], torch.tensor([3]))
        reference.zero_grad()
        ((cands.low + torch.sigmoid(logit) * (cands.high - cands.low)) * weights).sum().backward()
        reference.step()
        torch.testing.assert_close(cands.logits[3].detach(), logit.detach())
    assert all(
        torch.equal(p, q) for p, q in zip(others, [p for i, p in enumerate(cands.logits) if i != 3])
    )
    # the checkpoint keeps each candidate's moments and step count, runs first
    state = cands.state_dict()
    assert (
        state["step"].shape == (1, 5, 1)
        and state["step"][0, 3, 0] == 4
        and state["step"][0, 0, 0] == 0
    )
    restored, _ = _candidates(np.zeros(2), np.ones(2), seed=2)
    restored.load_state_dict(state)
    for a, b in ((cands, restored),):
        a.step(a.values()[0, 3].sum()[None], torch.tensor([3]))
        b.step(b.values()[0, 3].sum()[None], torch.tensor([3]))
    assert all(torch.equal(p, q) for p, q in zip(cands.logits, restored.logits))


def test_rarl_trains_against_a_rate_limited_adversary_and_is_evaluated_in_that_game(tmp_path):
    from rrls.agents.algos import rarl
    from rrls.evaluation import evaluate_run_dynamic
    from rrls.evaluation.policies import MLPPolicy

    out = tmp_path / "tc"
    assert (
        _cli_train(out, "rarl", steps=200, extra=["--uncertainty", "2d", "--rate-limit", "0.05"])
        == 0
    )
    meta = MLPPolicy.load(out / "adversary.npz").metadata
    assert meta["rate_limit"] == 0.05 and meta["game"] == "adversarial"
    assert meta["rate_game"] == "tc" and meta["omniscient"] is True  # the authors' defaults
    assert meta["observe"] == "vanilla" and meta["obs_dim"] == 2 + 4 + 1  # [ψ01, s] and a
    assert MLPPolicy.load(out / "policy.npz").obs_dim == 4
    assert json.loads((out / "run.json").read_text())["config"]["hyper"]["rate_limit"] == 0.05
    result = evaluate_run_dynamic(out, episodes=1)
    assert "rate_limit=0.05, rate_game=tc" in result.env_id
    # the training game: each parameter moves at most 0.05 per step, in raw units
    game = rarl.make_env("invertedpendulum", "2d", rarl.Config(rate_limit=0.05))
    box = game.uncertainty_set
    _, info = game.reset(seed=0)
    start = info["psi"]
    for t in range(1, 21):
        *_, info = game.step((np.zeros(1), np.ones(2)))
        assert np.allclose(info["psi"], np.minimum(start + 0.05 * t, box.high), atol=1e-12)
        assert np.allclose(box.to_array(game.get_params()), info["psi"], atol=0)


def test_rate_limit_is_refused_for_algorithms_without_an_adversary(tmp_path, capsys):
    assert _cli_train(tmp_path / "x", "td3", steps=200, extra=["--rate-limit", "0.05"]) == 2
    assert "--rate-limit does not apply to td3 (only to rarl)" in capsys.readouterr().err
    with pytest.raises(ValueError, match="rate_limit must be a finite number > 0"):
        hyperparameters(TrainConfig(algo="rarl", hyper={"rate_limit": -1.0}))


def test_no_private_torch_api_anywhere_in_rrls():
    # the training core is plain PyTorch: no torch._* / ATen calls, no nn.Module internals
    import re
    from pathlib import Path

    root = Path(__file__).resolve().parents[1] / "rrls"
    private = re.compile(
        r"torch\._[a-zA-Z]|torch\.ops\.|\baten\.|_load_from_state_dict|\._parameters\b"
        r"|nn\.Module\._apply|\bsuper\(\)\._apply"
    )
    hits = [
        f"{path.relative_to(root)}:{n}"
        for path in sorted(root.rglob("*.py"))
        for n, line in enumerate(path.read_text().splitlines(), 1)
        if private.search(line)
    ]
    assert not hits, hits
