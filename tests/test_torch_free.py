"""The torch-free side stays torch-free: environments, wrappers, evaluation, the benchmark's
and the report's reading side (specs, references, the store, statistics) and a run's settings
(``TrainConfig``'s fields, which ``rrls benchmark``'s options are made of) work in an interpreter
where ``import torch`` fails, so a user without the ``train`` extra loses nothing of them."""

from __future__ import annotations

import subprocess
import sys
import textwrap
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

SCRIPT = textwrap.dedent(
    """
    import sys

    class NoTorch:  # any import of torch fails, as on a machine without it
        def find_spec(self, name, path=None, target=None):
            if name == "torch" or name.startswith("torch."):
                raise ImportError("torch is blocked in this test")
            return None

    sys.meta_path.insert(0, NoTorch())

    import gymnasium as gym
    import rrls, rrls.envs, rrls.wrappers, rrls.evaluation
    import rrls.benchmark, rrls.report, rrls.submissions
    from rrls.evaluation import MLPPolicy, evaluate
    from rrls.benchmark import benchfile, store
    from rrls.report.reference import load_reference
    from rrls.benchmark.grid import PRESETS, Benchmark, validate

    env = gym.make("rrls/robust-hopper-v0")
    env.reset(seed=0)
    validate(Benchmark(**{**PRESETS["smoke"], "split": "extrapolation:0.5"}))
    spec = benchfile.read_spec(sys.argv[1] + "/docs/results/hopper-200k")
    assert spec.fingerprints()["protocol"]
    load_reference("hopper-200k")
    store.read_result(sys.argv[1] + "/docs/results/hopper-200k/runs/td3-hopper-3d-seed0")
    run = sys.argv[1] + "/docs/results/hopper-200k/runs/td3-hopper-3d-seed0"
    assert MLPPolicy.load(run + "/policy.npz").obs_dim == 11
    result = evaluate(MLPPolicy.random(4, 1, (8,), seed=0), "invertedpendulum", "1d", mesh=2,
                      episodes=1, workers=1)
    assert result.worst_case == result.worst_case
    # a run's settings are read without torch: rrls benchmark's options are generated from them
    import argparse, rrls.agents
    from rrls.agents.config import TrainConfig
    from rrls.cli import benchmark_command
    sub = argparse.ArgumentParser().add_subparsers()
    assert "--steps N" in benchmark_command.add_parser(sub).format_help()
    assert not [m for m in sys.modules if m == "torch" or m.startswith("torch.")]
    print("ok")
    """
)


def test_the_torch_free_side_works_without_torch():
    done = subprocess.run(
        [sys.executable, "-c", SCRIPT, str(ROOT)], capture_output=True, text=True, timeout=300
    )
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.strip().endswith("ok")
