"""RARL in TC-RMDP's game (``rrls train --algo rarl --rate-limit R``): the Stacked and Oracle
protagonists, exact resume, and the options' checks."""

from __future__ import annotations

import pytest
from conftest import stopping_at

torch = pytest.importorskip("torch")

from rrls.agents import TrainConfig, hyperparameters  # noqa: E402
from rrls.agents.run import read_checkpoint  # noqa: E402
from rrls.cli import main  # noqa: E402
from rrls.rundir import CHECKPOINT  # noqa: E402


def _cli_train(out, steps=200, extra=()):
    args = ["train", "--algo", "rarl", "--task", "invertedpendulum", "--steps", str(steps)]
    args += ["--learning-starts", "100", "--eval-every", "150", "--seed", "1"]
    args += ["--out", str(out), "--checkpoint-every", "50", "--hidden", "16", "16"]
    return main([*args, "--batch-size", "32", *extra])


def flat(state, prefix=""):
    """A nested checkpoint state as {dotted name: value}."""
    if isinstance(state, dict):
        return {k: v for key, sub in state.items() for k, v in flat(sub, f"{prefix}{key}.").items()}
    if isinstance(state, list | tuple):
        return {k: v for i, sub in enumerate(state) for k, v in flat(sub, f"{prefix}{i}.").items()}
    return {prefix[:-1]: state}


def _checkpoint(run_dir):
    return read_checkpoint(run_dir / CHECKPOINT)


@pytest.mark.parametrize("observe", ["stacked", "oracle"])
def test_rarl_trains_the_stacked_and_oracle_protagonists(tmp_path, observe):
    from rrls.evaluation import evaluate, evaluate_run_dynamic
    from rrls.evaluation.policies import MLPPolicy

    extra = ["--uncertainty", "2d", "--rate-limit", "0.01", "--observe", observe]
    extra += ["--history", "2", "--no-omniscient"] if observe == "stacked" else []
    assert _cli_train(tmp_path / observe, extra=extra) == 0
    policy = MLPPolicy.load(tmp_path / observe / "policy.npz")
    adversary = MLPPolicy.load(tmp_path / observe / "adversary.npz")
    # stacked, history 2: 3 states and 2 actions; oracle: s and ψ01; adversary [ψ01, s] (+ a)
    assert policy.obs_dim == {"stacked": 3 * 4 + 2, "oracle": 4 + 2}[observe]
    assert adversary.obs_dim == {"stacked": 6, "oracle": 7}[observe]
    assert policy.metadata["observe"] == observe
    # both evaluations show the protagonist what it trained on (periodic ones ran at step 150)
    assert "eval/nominal_return" in (tmp_path / observe / "scalars.csv").read_text()
    assert evaluate(policy, "invertedpendulum", "2d", mesh=2, episodes=1, workers=1)
    assert f"observe={observe}" in evaluate_run_dynamic(tmp_path / observe, episodes=1).env_id


@pytest.mark.e2e
def test_a_killed_and_resumed_tc_run_ends_bit_identical(tmp_path):
    # the episode in progress is replayed: uniform start, moves and the stacked history
    extra = ["--uncertainty", "2d", "--rate-limit", "0.01", "--observe", "stacked"]
    extra += ["--phase-steps", "70"]
    assert _cli_train(tmp_path / "whole", 400, extra) == 0
    with stopping_at(220):
        assert _cli_train(tmp_path / "cut", 400, extra) == 3
    assert _cli_train(tmp_path / "cut", 400, [*extra, "--resume"]) == 0
    sa, sb = (flat(_checkpoint(tmp_path / d)["learner"]) for d in ("whole", "cut"))
    assert sa.keys() == sb.keys()
    assert all(
        torch.equal(v, sb[k]) if isinstance(v, torch.Tensor) else v == sb[k] for k, v in sa.items()
    )


@pytest.mark.parametrize(
    "hyper, message",
    [
        ({"observe": "oracle"}, "observe='oracle' applies to TC-RMDP's game"),
        ({"omniscient": False}, "omniscient=False applies to TC-RMDP's game"),
        ({"rate_game": "target"}, "rate_game='target' needs rate_limit"),
        ({"rate_limit": 0.1, "rate_game": "target", "observe": "stacked"}, "applies to TC-RMDP"),
        ({"rate_limit": 0.1, "observe": "psychic"}, "observe must be one of vanilla, stacked"),
        ({"rate_limit": 0.1, "history": 2}, "history=2 applies to observe='stacked'"),
        ({"rate_limit": 0.1, "observe": "stacked", "history": 0}, "history must be an integer"),
        ({"rate_limit": 0.1, "rate_game": "fast"}, "rate_game must be one of tc, target"),
    ],
)
def test_the_tc_options_are_checked(hyper, message):
    with pytest.raises(ValueError, match=message):
        hyperparameters(TrainConfig(algo="rarl", hyper=hyper))


def test_the_oracle_trains_on_parameter_sets_only():
    from rrls.agents.algos import rarl

    oracle = rarl.Config(rate_limit=0.1, observe="oracle")
    with pytest.raises(ValueError, match="train the oracle on a parameter set"):
        rarl.make_env("invertedpendulum", "rarl", oracle)
    assert rarl.make_env("invertedpendulum", "2d", oracle).views == ((0, 6), (6, 12))
