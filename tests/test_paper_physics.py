"""paper=True: the paper's physics (the Gymnasium v5 envs the original code built at the paper's
time, its parameter writes, the np.arange mesh) on demand; the default stays v5 with rrls's
semantics; results record which."""

from __future__ import annotations

import copy
import json
import pickle
import warnings

import gymnasium as gym
import numpy as np
import pytest

from rrls.envs import ROBUST_ENVS, RobustHopper, RobustWalker2d
from rrls.evaluation import evaluate


def _plain(env_id: str) -> gym.Env:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        return gym.make(env_id)


def _rollout(env, actions, seed=0):
    obs, _ = env.reset(seed=seed)
    out = [obs]
    for a in actions:
        obs, _, term, trunc, _ = env.step(a)
        out.append(obs)
        if term or trunc:
            break
    return np.array(out)


#: what the original code builds at the paper's time: SuReLI/RRLS@428665c (2024-06-06, pins
#: gymnasium==1.0.0a1), rrls/envs/<file>, gym.make("<Task>-v5") since 68beb84 (2023-11-28)
ORIGINAL_IDS = {
    "ant": "Ant-v5",  # ant.py:96
    "halfcheetah": "HalfCheetah-v5",  # half_cheetah.py:82
    "hopper": "Hopper-v5",  # hopper.py:67
    "humanoidstandup": "HumanoidStandup-v5",  # humanoid.py:94
    "invertedpendulum": "InvertedPendulum-v5",  # pendulum.py:52
    "walker": "Walker2d-v5",  # walker.py:77
}


def test_paper_physics_builds_the_envs_the_original_code_built_at_the_papers_time():
    from rrls.tasks import TASKS

    assert {k: t.paper_id for k, t in TASKS.items() if t.paper_id} == ORIGINAL_IDS


@pytest.mark.parametrize("task", ["hopper", "walker", "ant"])
def test_paper_env_is_the_original_codes_v5_env_bit_for_bit(task):
    env = gym.make(f"rrls/robust-{task}-v0", paper=True)
    assert type(env.unwrapped).__name__.startswith("PaperRobust")
    assert env.unwrapped.paper and not gym.make(f"rrls/robust-{task}-v0").unwrapped.paper
    plain = _plain(ORIGINAL_IDS[task])
    assert env.observation_space.shape == plain.observation_space.shape
    actions = np.random.default_rng(0).uniform(-1, 1, (50, *plain.action_space.shape))
    np.testing.assert_array_equal(_rollout(env, actions), _rollout(plain, actions))


def test_paper_worldfriction_writes_the_floor_only():
    env = RobustWalker2d(paper=True)
    env.set_params(worldfriction=0.3)
    friction = env.model.geom_friction[:, 0]
    assert friction[0] == 0.3 and friction[4] == 1.9 and friction[7] == 1.9  # v5's feet
    assert RobustWalker2d(worldfriction=0.3).model.geom_friction[:, 0].tolist() == [0.3] * 8
    env.reset_params()
    assert env.model.geom_friction[0, 0] == 0.7


@pytest.mark.parametrize("how", ["deepcopy", "pickle"])
def test_paper_envs_copy_as_paper_envs(how):
    env = RobustHopper(paper=True, torsomass=2.0)
    twin = copy.deepcopy(env) if how == "deepcopy" else pickle.loads(pickle.dumps(env))
    assert type(twin) is type(env) and twin.paper and twin.get_params() == env.get_params()


def test_tasks_without_paper_physics_refuse_it():
    with pytest.raises(ValueError, match="RobustSwimmer has no paper physics"):
        ROBUST_ENVS["swimmer"](paper=True)
    with pytest.raises(ValueError, match="has no paper physics"):
        evaluate(lambda o: np.zeros((len(o), 2)), "swimmer", "1d", paper=True, workers=1)


def test_evaluate_paper_uses_the_arange_mesh_and_records_it(tmp_path):
    def policy(obs):
        return np.tanh(obs[:, :3])

    paper = evaluate(
        policy, "hopper", "1d", mesh=3, episodes=1, workers=1, max_episode_steps=30,
        paper=True, out_dir=tmp_path / "paper",
    )  # fmt: skip
    assert paper.episodes["worldfriction"].round(6).tolist() == [0.1, 1.066667, 2.033333]
    summary = json.loads((tmp_path / "paper" / "summary.json").read_text())
    assert summary["physics"] == "paper" and summary["endpoint"] is False
    for _, row in paper.episodes.iterrows():
        env = gym.make("rrls/robust-hopper-v0", paper=True, max_episode_steps=30)
        env.set_params(worldfriction=row["worldfriction"])
        obs, _ = env.reset(seed=int(row["seed"]))
        total, done = 0.0, False
        while not done:
            obs, r, term, trunc, _ = env.step(policy(obs[None])[0])
            total += r
            done = term or trunc
        assert total == row["return"]
    v5 = evaluate(policy, "hopper", "1d", mesh=3, episodes=1, workers=1, max_episode_steps=30)
    assert v5.episodes["worldfriction"].tolist()[-1] == 3.0
    assert v5.summary()["physics"] == "v5"


def test_cli_evaluate_physics_paper(tmp_path, capsys):
    from rrls.cli import main
    from rrls.evaluation.policies import MLPPolicy

    MLPPolicy.random(4, 1, (8,), seed=0).save(tmp_path / "p.npz")
    args = ["evaluate", str(tmp_path / "p.npz"), "--task", "invertedpendulum"]
    args += ["--uncertainty", "1d", "--mesh", "2", "--episodes", "1", "--workers", "1"]
    assert main([*args, "--physics", "paper", "--out", str(tmp_path / "e")]) == 0
    assert "(paper physics)" in capsys.readouterr().out
    summary = json.loads((tmp_path / "e" / "summary.json").read_text())
    assert summary["physics"] == "paper" and summary["endpoint"] is False


def test_physics_labels_are_one_vocabulary_and_old_ones_read_as_today():
    from rrls.physics import PAPER, V5, physics_label

    assert [physics_label(v) for v in ("v5", "rrls-v5", None, False)] == [V5] * 4
    assert [physics_label(v) for v in ("paper", "PAPER", True)] == [PAPER] * 3
    # the v4 labels named physics paper=True no longer builds: refused, not read as v5
    for old in ("paper-v4", "v4"):
        with pytest.raises(ValueError, match=f"physics '{old}' is the paper's physics on Gym"):
            physics_label(old)
    assert (V5, PAPER) == ("v5", "paper")  # recorded as --physics says it
    with pytest.raises(ValueError, match="unknown physics 'v3'; valid: v5"):
        physics_label("v3")


def test_train_physics_paper_uses_the_paper_twin_and_records_it(tmp_path):
    pytest.importorskip("torch")
    from rrls.agents import TrainConfig, algorithm, hyperparameters, train
    from rrls.agents.envs import env_factory
    from rrls.evaluation.policies import MLPPolicy

    small = {"hidden": (8, 8), "batch_size": 16, "learning_starts": 50}
    config = TrainConfig(
        algo="rarl", task="hopper", uncertainty="1d", steps=80, seed=0, out=str(tmp_path / "r"),
        eval_every=0, checkpoint_every=80, physics="paper", hyper=small, progress=False,
    )  # fmt: skip
    assert config.physics == "paper" and config.max_episode_steps == 1000
    env = env_factory(algorithm("rarl"), config, hyperparameters(config))()
    assert type(env.unwrapped).__name__ == "PaperRobustHopper" and env.unwrapped.paper
    v5 = env_factory(
        algorithm("rarl"), TrainConfig(algo="rarl", task="hopper"), hyperparameters(config)
    )()
    assert type(v5.unwrapped).__name__ == "RobustHopper"
    run = train(config)
    assert json.loads((run / "run.json").read_text())["config"]["physics"] == "paper"
    assert MLPPolicy.load(run / "adversary.npz").metadata["physics"] == "paper"
    from rrls.evaluation import evaluate_run_dynamic

    assert evaluate_run_dynamic(run, episodes=1).env_id.endswith("[paper]")
    from rrls.cli import main

    args = ["evaluate", str(run), "--mesh", "2", "--episodes", "1", "--workers", "1"]
    assert main([*args, "--out", str(tmp_path / "e")]) == 0  # the run's physics by default
    assert json.loads((tmp_path / "e" / "summary.json").read_text())["physics"] == "paper"
    with pytest.raises(ValueError, match="task 'swimmer' has no paper physics; valid with"):
        TrainConfig(task="swimmer", physics="paper")


def test_a_reference_of_other_physics_is_refused_for_a_paper_benchmark():
    from rrls.benchmark.grid import SpecError, make_spec
    from rrls.report.reference import ReferenceError, check_compatible, load_reference

    spec = make_spec("quick", physics="paper")
    assert spec.physics == "paper" and spec.to_json()["protocol"]["physics"] == "paper"
    quick = load_reference("quick")  # measured on v5 (its file says rrls-v5)
    with pytest.raises(ReferenceError, match="physics: 'v5' there, 'paper' here"):
        check_compatible(quick, spec.to_json())
    check_compatible(quick, make_spec("quick").to_json())  # same physics: accepted
    old = {**make_spec("quick").flat_json(), "physics": "rrls-v5"}  # an older file, label
    check_compatible(quick, old)
    with pytest.raises(SpecError, match="task 'swimmer' has no paper physics"):
        make_spec("smoke", tasks="swimmer", uncertainty="1d", physics="paper")


def test_a_plugin_make_env_without_paper_is_refused_on_the_papers_physics():
    pytest.importorskip("torch")
    from rrls.agents import TrainConfig, algorithm
    from rrls.agents.envs import env_factory

    def make_env(task, uncertainty, config):
        raise AssertionError("not called")

    plugin = algorithm("td3")._replace(name="mine", make_env=make_env)
    with pytest.raises(ValueError, match="'mine': its make_env takes no 'paper' keyword"):
        env_factory(plugin, TrainConfig(task="hopper", physics="paper"), None)
    assert env_factory(plugin, TrainConfig(task="hopper"), None).func is make_env


def test_the_paper_physics_script_claims_a_run_while_its_process_lives(tmp_path):
    # benchmarks/paper_physics.py, several processes on one folder: a run is each one's once,
    # and a claim left by a process stopped part-way does not keep the run from the next one
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
    from paper_physics import take

    claim = tmp_path / ".paper_physics.td3-hopper-3d-seed0.claim"
    first = take(claim)
    assert first is not None and take(claim) is None  # held: the other process skips the run
    first.close()  # its process ends (or is killed): the lock goes with it
    claim.touch()  # the file left behind is no claim
    second = take(claim)
    assert second is not None
    second.close()


def test_the_paper_physics_script_times_a_run_over_all_its_pieces(tmp_path, monkeypatch):
    # a run's evaluation stopped part-way and resumed: its row states the time of both pieces;
    # where a piece's time is unknown (chunks without it), the row states none rather than less
    import csv
    import shutil
    import sys
    from pathlib import Path
    from types import SimpleNamespace

    root = Path(__file__).resolve().parents[1]
    sys.path.insert(0, str(root / "benchmarks"))
    import paper_physics

    shipped = root / "docs" / "results" / "hopper"
    shutil.copy(shipped / "benchmark.json", tmp_path)
    shutil.copy(shipped / "benchmark.json.sha256", tmp_path)
    run = "td3-hopper-3d-seed0"
    shutil.copytree(shipped / "runs" / run, tmp_path / "runs" / run)
    clock = iter(range(0, 10_000, 100))
    monkeypatch.setattr(paper_physics.time, "time", lambda: float(next(clock)))
    calls = []

    def evaluate(policy, task, protocol, workers, out_dir):
        assert protocol.physics == "paper"
        calls.append(out_dir)
        (out_dir / "chunks").mkdir(parents=True, exist_ok=True)
        if len(calls) == 1:
            raise KeyboardInterrupt  # the first piece stops part-way
        return SimpleNamespace(worst_case=1.0, average_case=2.0)

    monkeypatch.setattr(paper_physics, "evaluate", evaluate)
    monkeypatch.setattr(sys, "argv", ["paper_physics.py", str(tmp_path)])
    with pytest.raises(KeyboardInterrupt):
        paper_physics.main()
    assert (calls[0] / "seconds").read_text() == "100.0"  # kept beside the chunks

    def second(policy, task, protocol, workers, out_dir):
        # while a piece runs, no time is on file: were its machine to vanish, the next piece
        # would find chunks without a time and state none, never the first piece's alone
        assert not (out_dir / "seconds").exists()
        return evaluate(policy, task, protocol, workers, out_dir)

    monkeypatch.setattr(paper_physics, "evaluate", second)
    paper_physics.main()
    with open(tmp_path / "paper_physics.csv", newline="") as f:
        (row,) = csv.DictReader(f)
    assert (row["run"], row["worst_case_paper"], row["seconds"]) == (run, "1.0", "200.0")
    assert not calls[0].exists()  # removed once the row is written

    chunks = tmp_path / ".paper_physics" / "other"
    assert paper_physics.spent_before(chunks) == 0.0  # a fresh start
    (chunks / "chunks").mkdir(parents=True)
    assert paper_physics.spent_before(chunks) is None  # chunks whose time is unknown
    (chunks / "seconds").write_text("12.5")
    assert paper_physics.spent_before(chunks) == 12.5
