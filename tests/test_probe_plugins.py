"""Outside probes of plug-in learners (issue 26): what is no learner is one line (exit 2), and a
learner that diverges stops training instead of writing a NaN policy."""

from __future__ import annotations

import os
import sys
import textwrap
from pathlib import Path

import pytest

torch = pytest.importorskip("torch")

from rrls._progress import PLAIN_LINE  # noqa: E402
from rrls.cli import main  # noqa: E402

EXAMPLES = Path(__file__).resolve().parents[1] / "docs" / "examples"
SMALL = ["--hidden", "8", "8", "--batch-size", "16", "--learning-starts", "50"]

MODULES = {
    "probeplug": """
        class NotALearner:
            def act(self, obs):
                return obs


        def function():
            return 1
    """,
    "probeboom": """
        raise RuntimeError("boom on import\\nsecond line")
    """,
    "probenan": """
        import torch
        from ddpg import Learner as DDPG


        class Learner(DDPG):
            '''DDPG whose actor turns NaN at its first update (a diverged learner).'''

            def update(self, step):
                out = super().update(step)
                with torch.no_grad():
                    for p in self.actor.parameters():
                        p.fill_(float("nan"))
                return out
    """,
}


@pytest.fixture
def modules(tmp_path, monkeypatch):
    for name, text in MODULES.items():
        (tmp_path / f"{name}.py").write_text(textwrap.dedent(text))
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.syspath_prepend(str(EXAMPLES))
    path = os.pathsep.join([str(tmp_path), str(EXAMPLES), os.environ.get("PYTHONPATH", "")])
    monkeypatch.setenv("PYTHONPATH", path)
    yield tmp_path
    for name in (*MODULES, "ddpg"):
        sys.modules.pop(name, None)


def _train(out: Path, algo: str, steps: int = 120) -> int:
    args = ["train", "--algo", algo, "--task", "invertedpendulum", "--steps", str(steps)]
    return main([*args, "--eval-every", "0", "--out", str(out), *SMALL])


@pytest.mark.parametrize(
    ("algo", "says"),
    [
        ("probeplug:NotALearner", "lacks observe, update, state_dict, load_state_dict, export"),
        ("json:loads", "json:loads is a function: not a learner"),
        ("probeplug:function", "is a function: not a learner"),
        ("probeboom:Learner", "cannot load probeboom:Learner (RuntimeError: boom on import)"),
    ],
)
def test_what_is_no_learner_is_one_line(modules, tmp_path, capsys, algo, says):
    assert _train(tmp_path / "run", algo) == 2
    err = capsys.readouterr().err.strip()
    assert says in err and "\n" not in err and "Traceback" not in err
    assert not (tmp_path / "run" / "policy.npz").exists()
    bench = ["benchmark", "--out", str(tmp_path / "bench"), "--preset", "smoke"]
    assert main([*bench, "--algos", f"td3,{algo}"]) == 2
    err = capsys.readouterr().err.strip()
    assert says in err and "\n" not in err
    assert not (tmp_path / "bench" / "runs").exists()


def test_a_learner_with_nan_actions_stops_without_writing_a_policy(modules, tmp_path, capsys):
    out = tmp_path / "nan"
    assert _train(out, "probenan:Learner", steps=200) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    err = "\n".join(line for line in lines if not PLAIN_LINE.match(line))  # progress aside
    assert "training stopped at step 52" in err and "non-finite action" in err
    assert "\n" not in err
    assert not (out / "policy.npz").exists() and not (out / "run.json").exists()


def test_a_learner_exporting_nan_weights_is_refused(modules, tmp_path):
    import numpy as np

    from rrls.agents import Diverged
    from rrls.agents.run import export_policies
    from rrls.evaluation.policies import MLPPolicy

    bad = MLPPolicy([np.full((3, 2), np.nan)], [np.zeros(2)])

    class Exporter:
        def export(self, k):
            return {"policy": bad}

    with pytest.raises(Diverged, match="the policy of seed 4 has non-finite"):
        export_policies(Exporter(), 0, {"seed": 4})
