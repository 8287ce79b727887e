"""The learner protocol's hidden contract made loud: a learner whose state is not runs-first
(a one-run learner built on plain ``nn.Linear``) is refused at its first checkpoint, naming
the tensor, instead of checkpointing a wrong slice that only a resume would reveal."""

from __future__ import annotations

import pytest

torch = pytest.importorskip("torch")

from rrls.agents import LearnerProtocol, StateLayoutError, TrainConfig, train  # noqa: E402
from rrls.agents.algos.td3 import Learner as TD3Learner  # noqa: E402


class FlatLearner(TD3Learner):
    """TD3, but its state also holds a plain one-run layer (``weight`` is ``(out, in)``)."""

    def state_dict(self) -> dict:
        return {**super().state_dict(), "extra": {"weight": torch.zeros(5, 3)}}


def test_a_state_that_is_not_runs_first_is_refused_at_the_first_checkpoint(tmp_path):
    config = TrainConfig(
        algo=f"{__name__}:FlatLearner",
        task="invertedpendulum",
        steps=120,
        checkpoint_every=50,
        eval_every=0,
        out=str(tmp_path / "run"),
        hyper={"hidden": (8,), "batch_size": 16, "learning_starts": 40},
    )
    with pytest.raises(StateLayoutError, match=r"\['extra'\]\['weight'\] has shape \(5, 3\)"):
        train(config)


def test_the_built_in_learners_satisfy_the_typed_protocol():
    from rrls.agents import ALGOS, algorithm

    for name in ALGOS:
        learner = algorithm(name).Learner
        assert all(callable(getattr(learner, m, None)) for m in ("act", "update", "export"))
        assert issubclass(learner, LearnerProtocol)


def test_the_device_resident_methods_are_where_they_work():
    """Every built-in learner has the device-resident loop's methods: TD3's and SAC's (so DR
    and SAC-DR), NR-MDP's (the executed action), RARL's (the joint action of the twin's force
    game) and M2TD3's, which adds the choice of each episode's point (``begin_episodes``)."""
    from rrls.agents import ALGOS, DeviceLearnerProtocol, algorithm

    has = {name: issubclass(algorithm(name).Learner, DeviceLearnerProtocol) for name in ALGOS}
    assert {name for name, yes in has.items() if yes} == set(ALGOS)
    choosers = {name for name in ALGOS if hasattr(algorithm(name).Learner, "begin_episodes")}
    assert choosers == {"m2td3"}
