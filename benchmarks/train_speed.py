"""TD3 training speed: rrls' TD3 core against CleanRL's TD3, side by side.

One run, this machine, Hopper (nominal), the paper's sizes (256-256, batch 256), one update per
env step after learning starts. Env steps per second of:

(a) CleanRL's loop: ``td3_continuous_action.py`` as published, step for step (``cleanrl``
    below: its vector env, its replay buffer, which is Stable-Baselines3's, its TensorBoard
    logging). Needs ``stable-baselines3`` (``pip install -e .[bench]``); the row is skipped
    without it;
(a') the same update in a lean loop (``straightforward``): two separate critic modules, a
    Python loop over parameters for Polyak averaging, plain Adam, numpy<->torch conversion of
    every transition and batch, no vector env, a list replay;
(a'') (a') with denormals flushed to zero, to separate that one setting (which ``rrls train``
    makes) from the rest of the work;
(b) ``rrls.agents`` TD3 (batched twin critic, explicit back-propagation, the fused Adam kernel
    called directly, ``_foreach_lerp_``, tensor replay, acting in numpy);
(c) M2TD3 (``rrls.agents.m2td3``) for reference.

Every measurement runs in a fresh process. Ratios are against (a) and against (a').

Target: (b) >= 2x the straightforward version. Measured after learning starts and ``--warmup``
updates (default 3 000: enough for dead units' Adam moments to reach the denormal range, as in
real training).

    python benchmarks/train_speed.py [--task hopper] [--steps 600] [--warmup 3000] [--rounds 3]
"""

from __future__ import annotations

import argparse
import importlib.util
import multiprocessing
import statistics
import tempfile
import time
import warnings

import gymnasium as gym
import numpy as np
import torch
import torch.nn.functional as F  # noqa: N812
from torch import nn

from rrls.agents.common import TrainConfig, make_env


# -- (a) the straightforward version ---------------------------------------------------------------
class QNetwork(nn.Module):
    def __init__(self, obs_dim: int, act_dim: int) -> None:
        super().__init__()
        self.fc1 = nn.Linear(obs_dim + act_dim, 256)
        self.fc2 = nn.Linear(256, 256)
        self.fc3 = nn.Linear(256, 1)

    def forward(self, x: torch.Tensor, a: torch.Tensor) -> torch.Tensor:
        x = torch.cat([x, a], 1)
        return self.fc3(F.relu(self.fc2(F.relu(self.fc1(x)))))


class ActorNet(nn.Module):
    def __init__(self, obs_dim: int, act_dim: int, scale: np.ndarray, bias: np.ndarray) -> None:
        super().__init__()
        self.fc1 = nn.Linear(obs_dim, 256)
        self.fc2 = nn.Linear(256, 256)
        self.fc_mu = nn.Linear(256, act_dim)
        self.register_buffer("action_scale", torch.tensor(scale, dtype=torch.float32))
        self.register_buffer("action_bias", torch.tensor(bias, dtype=torch.float32))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        x = torch.tanh(self.fc_mu(F.relu(self.fc2(F.relu(self.fc1(x))))))
        return x * self.action_scale + self.action_bias


def straightforward(task: str, steps: int, warmup: int, seed: int = 0) -> float:
    """CleanRL-style TD3; returns env steps/s over ``steps`` steps after ``warmup`` updates."""
    env = make_env(task)
    obs_dim, act_dim = env.observation_space.shape[0], env.action_space.shape[0]
    low, high = env.action_space.low, env.action_space.high
    torch.manual_seed(seed)
    rng = np.random.default_rng(seed)
    actor = ActorNet(obs_dim, act_dim, (high - low) / 2, (high + low) / 2)
    qf1, qf2 = QNetwork(obs_dim, act_dim), QNetwork(obs_dim, act_dim)
    qf1_target, qf2_target = QNetwork(obs_dim, act_dim), QNetwork(obs_dim, act_dim)
    target_actor = ActorNet(obs_dim, act_dim, (high - low) / 2, (high + low) / 2)
    target_actor.load_state_dict(actor.state_dict())
    qf1_target.load_state_dict(qf1.state_dict())
    qf2_target.load_state_dict(qf2.state_dict())
    q_optimizer = torch.optim.Adam(list(qf1.parameters()) + list(qf2.parameters()), lr=3e-4)
    actor_optimizer = torch.optim.Adam(list(actor.parameters()), lr=3e-4)
    buffer: list[tuple] = []
    obs, _ = env.reset(seed=seed)
    for _ in range(1000):  # a filled buffer to sample from
        action = rng.uniform(low, high)
        next_obs, reward, terminated, _, _ = env.step(action)
        buffer.append((obs, action, reward, next_obs, terminated))
        obs = next_obs if not terminated else env.reset()[0]
    start = None
    for step in range(warmup + steps):
        if step == warmup:
            start = time.perf_counter()
        with torch.no_grad():
            action = actor(torch.Tensor(obs).unsqueeze(0))
            action += torch.normal(0, actor.action_scale * 0.1)
            action = action.cpu().numpy().clip(low, high)[0]
        next_obs, reward, terminated, _, _ = env.step(action)
        buffer.append((obs, action, reward, next_obs, terminated))
        obs = next_obs if not terminated else env.reset()[0]

        idx = rng.integers(0, len(buffer), 256)
        o, a, r, no, d = (np.array(x) for x in zip(*(buffer[i] for i in idx)))
        o, a, no = torch.Tensor(o), torch.Tensor(a), torch.Tensor(no)
        r, d = torch.Tensor(r).flatten(), torch.Tensor(d.astype(np.float32)).flatten()
        with torch.no_grad():
            clipped_noise = (torch.randn_like(a) * 0.2).clamp(-0.5, 0.5) * target_actor.action_scale
            next_a = (target_actor(no) + clipped_noise).clamp(torch.Tensor(low), torch.Tensor(high))
            min_q = torch.min(qf1_target(no, next_a), qf2_target(no, next_a))
            next_q = r + (1 - d) * 0.99 * min_q.view(-1)
        qf1_loss = F.mse_loss(qf1(o, a).view(-1), next_q)
        qf2_loss = F.mse_loss(qf2(o, a).view(-1), next_q)
        q_optimizer.zero_grad()
        (qf1_loss + qf2_loss).backward()
        q_optimizer.step()
        if step % 2 == 0:
            actor_loss = -qf1(o, actor(o)).mean()
            actor_optimizer.zero_grad()
            actor_loss.backward()
            actor_optimizer.step()
            for net, target in ((actor, target_actor), (qf1, qf1_target), (qf2, qf2_target)):
                for param, target_param in zip(net.parameters(), target.parameters()):
                    target_param.data.copy_(0.005 * param.data + 0.995 * target_param.data)
    return steps / (time.perf_counter() - start)


def cleanrl(task: str, steps: int, warmup: int, seed: int = 0) -> float:
    """CleanRL's ``td3_continuous_action.py`` loop as published, on this stack.

    Everything the script does per step after learning starts: a one-env ``SyncVectorEnv`` of
    ``gym.make`` + ``RecordEpisodeStatistics``, its replay buffer (``cleanrl_utils.buffers`` is
    Stable-Baselines3's ``ReplayBuffer``: 1 M preallocated numpy rows, numpy indexing and a
    ``torch.tensor`` copy per field and batch), the update of ``straightforward`` (the same
    modules and lines), TensorBoard scalars every 100 steps. Two changes, neither timed: the
    ``print`` of steps/s is dropped, and a truncation does not read ``infos["final_observation"]``
    (Gymnasium 1.x no longer provides it: the published script stops there with a KeyError).
    """
    from stable_baselines3.common.buffers import ReplayBuffer as SB3ReplayBuffer
    from torch.utils.tensorboard import SummaryWriter

    from rrls.tasks import get_task

    def thunk() -> gym.Env:
        env = gym.wrappers.RecordEpisodeStatistics(gym.make(get_task(task).v5_id))
        env.action_space.seed(seed)
        return env

    envs = gym.vector.SyncVectorEnv([thunk])
    obs_dim = envs.single_observation_space.shape[0]
    act_dim = envs.single_action_space.shape[0]
    low, high = envs.single_action_space.low, envs.single_action_space.high
    np.random.seed(seed)  # noqa: NPY002 - SB3's buffer (CleanRL's) samples from the global one
    torch.manual_seed(seed)
    actor = ActorNet(obs_dim, act_dim, (high - low) / 2, (high + low) / 2)
    qf1, qf2 = QNetwork(obs_dim, act_dim), QNetwork(obs_dim, act_dim)
    qf1_target, qf2_target = QNetwork(obs_dim, act_dim), QNetwork(obs_dim, act_dim)
    target_actor = ActorNet(obs_dim, act_dim, (high - low) / 2, (high + low) / 2)
    target_actor.load_state_dict(actor.state_dict())
    qf1_target.load_state_dict(qf1.state_dict())
    qf2_target.load_state_dict(qf2.state_dict())
    q_optimizer = torch.optim.Adam(list(qf1.parameters()) + list(qf2.parameters()), lr=3e-4)
    actor_optimizer = torch.optim.Adam(list(actor.parameters()), lr=3e-4)
    envs.single_observation_space.dtype = np.float32
    rb = SB3ReplayBuffer(
        1_000_000,
        envs.single_observation_space,
        envs.single_action_space,
        "cpu",
        handle_timeout_termination=False,
    )
    learning_starts = 1000
    obs, _ = envs.reset(seed=seed)
    start = None
    with tempfile.TemporaryDirectory() as logdir:
        writer = SummaryWriter(logdir)
        for global_step in range(learning_starts + warmup + steps + 1):
            if global_step == learning_starts + warmup + 1:
                start = time.perf_counter()
            if global_step < learning_starts:
                actions = np.array([envs.single_action_space.sample()])
            else:
                with torch.no_grad():
                    actions = actor(torch.Tensor(obs))
                    actions += torch.normal(0, actor.action_scale * 0.1)
                    actions = actions.cpu().numpy().clip(low, high)
            next_obs, rewards, terminations, truncations, infos = envs.step(actions)
            if "final_info" in infos:
                for info in infos["final_info"]:
                    if info is not None:
                        writer.add_scalar("charts/episodic_return", info["episode"]["r"], 0)
                        break
            real_next_obs = next_obs.copy()
            for idx, trunc in enumerate(truncations):
                if trunc and "final_observation" in infos:
                    real_next_obs[idx] = infos["final_observation"][idx]
            rb.add(obs, real_next_obs, actions, rewards, terminations, infos)
            obs = next_obs
            if global_step > learning_starts:
                data = rb.sample(256)
                with torch.no_grad():
                    clipped_noise = (torch.randn_like(data.actions) * 0.2).clamp(
                        -0.5, 0.5
                    ) * target_actor.action_scale
                    next_state_actions = (
                        target_actor(data.next_observations) + clipped_noise
                    ).clamp(float(low[0]), float(high[0]))
                    qf1_next_target = qf1_target(data.next_observations, next_state_actions)
                    qf2_next_target = qf2_target(data.next_observations, next_state_actions)
                    min_qf_next_target = torch.min(qf1_next_target, qf2_next_target)
                    next_q_value = data.rewards.flatten() + (
                        1 - data.dones.flatten()
                    ) * 0.99 * min_qf_next_target.view(-1)
                qf1_a_values = qf1(data.observations, data.actions).view(-1)
                qf2_a_values = qf2(data.observations, data.actions).view(-1)
                qf1_loss = F.mse_loss(qf1_a_values, next_q_value)
                qf2_loss = F.mse_loss(qf2_a_values, next_q_value)
                qf_loss = qf1_loss + qf2_loss
                q_optimizer.zero_grad()
                qf_loss.backward()
                q_optimizer.step()
                if global_step % 2 == 0:
                    actor_loss = -qf1(data.observations, actor(data.observations)).mean()
                    actor_optimizer.zero_grad()
                    actor_loss.backward()
                    actor_optimizer.step()
                    for net, target in (
                        (actor, target_actor),
                        (qf1, qf1_target),
                        (qf2, qf2_target),
                    ):
                        for param, target_param in zip(net.parameters(), target.parameters()):
                            target_param.data.copy_(0.005 * param.data + 0.995 * target_param.data)
                if global_step % 100 == 0:
                    writer.add_scalar("losses/qf1_values", qf1_a_values.mean().item(), global_step)
                    writer.add_scalar("losses/qf2_values", qf2_a_values.mean().item(), global_step)
                    writer.add_scalar("losses/qf1_loss", qf1_loss.item(), global_step)
                    writer.add_scalar("losses/qf2_loss", qf2_loss.item(), global_step)
                    writer.add_scalar("losses/qf_loss", qf_loss.item() / 2.0, global_step)
                    writer.add_scalar("losses/actor_loss", actor_loss.item(), global_step)
                    writer.add_scalar("charts/SPS", global_step, global_step)
        elapsed = time.perf_counter() - start
        writer.close()
    envs.close()
    return steps / elapsed


# -- (b), (c) rrls ---------------------------------------------------------------------------------
def rrls_algo(algo: str, task: str, steps: int, warmup: int) -> float:
    """Env steps/s of ``rrls.agents`` after learning starts, timed at the env's ``step`` calls."""
    import importlib

    module = importlib.import_module(f"rrls.agents.{algo}")
    learning_starts = 1000
    stamps: list[float] = []

    class Clock(gym.Wrapper):
        def step(self, action):  # noqa: ANN001, ANN202
            stamps.append(time.perf_counter())
            return self.env.step(action)

    plain = module.make_env
    module.make_env = lambda *a, **k: Clock(plain(*a, **k))
    try:
        with tempfile.TemporaryDirectory() as out:
            config = TrainConfig(
                algo=algo,
                task=task,
                uncertainty="3d",
                steps=learning_starts + warmup + steps + 1,
                learning_starts=learning_starts,
                eval_every=0,
                out=out,
                progress=False,
                checkpoint_every=10**9,
            )
            module.train(config)
    finally:
        module.make_env = plain
    first = learning_starts + warmup
    return steps / (stamps[first + steps] - stamps[first])


def _measure(name: str, task: str, steps: int, warmup: int) -> float:
    warnings.simplefilter("ignore")
    if name == "cleanrl":
        return cleanrl(task, steps, warmup)
    if name in ("straightforward", "ftz"):
        if name == "ftz":
            torch.set_flush_denormal(True)
        return straightforward(task, steps, warmup)
    return rrls_algo(name, task, steps, warmup)


ROWS = {
    "cleanrl": "(a) CleanRL's loop as published (SB3 replay, vector env)",
    "straightforward": "(a') the same update, lean loop",
    "ftz": "(a'') (a') + flush denormals to zero",
    "td3": "(b) rrls TD3",
    "m2td3": "(c) rrls M2TD3 (batch 100, 5 candidates)",
}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--task", default="hopper")
    parser.add_argument("--steps", type=int, default=600)
    parser.add_argument("--warmup", type=int, default=3000)
    parser.add_argument("--rounds", type=int, default=3)
    args = parser.parse_args()
    warnings.simplefilter("ignore")
    names = list(ROWS)
    if importlib.util.find_spec("stable_baselines3") is None:
        print("stable-baselines3 is not installed: row (a) skipped (pip install -e .[bench])")
        names.remove("cleanrl")
    runs: dict[str, list[float]] = {k: [] for k in names}
    # each measurement in a fresh process: flush-to-zero is per thread and inherited, so one
    # implementation's setting must not leak into the next
    ctx = multiprocessing.get_context("spawn")
    with ctx.Pool(1, maxtasksperchild=1) as pool:
        for _ in range(args.rounds):
            for name in runs:
                job = (name, args.task, args.steps, args.warmup)
                runs[name].append(pool.apply(_measure, job))
    med = {k: statistics.median(v) for k, v in runs.items()}
    print(
        f"\n{args.task}, CPU ({torch.get_num_threads()} threads), 256-256, one update per env "
        f"step, median of {args.rounds} rounds x {args.steps} steps\n"
    )
    refs = [k for k in ("cleanrl", "straightforward") if k in med]
    print("| implementation | steps/s | " + " | ".join(f"ratio vs {k}" for k in refs) + " |")
    print("|---|---|" + "---|" * len(refs))
    for name, value in med.items():
        ratios = " | ".join(f"{value / med[k]:.2f}x" for k in refs)
        print(f"| {ROWS[name]} | {value:.0f} | {ratios} |")


if __name__ == "__main__":
    main()
