"""TD3 training speed: rrls' TD3 core against a straightforward CleanRL-style implementation.

Side by side in one run, on this machine, Hopper (nominal), the paper's sizes (256-256, batch
256), one update per env step after learning starts: env steps per second of

(a) the straightforward version — written the way CleanRL's ``td3_continuous_action.py`` writes
    it: two separate critic modules, a Python loop over parameters for Polyak averaging, plain
    Adam, numpy<->torch conversion of every transition and batch (a list-of-arrays replay);
(b) ``rrls.agents`` TD3 (batched twin critic, explicit back-propagation, the fused Adam kernel
    called directly, ``_foreach_lerp_``, tensor replay, acting in numpy);
(c) M2TD3 (``rrls.agents.m2td3``) for reference;
(a') the straightforward version with denormals flushed to zero, to separate that one setting
    (which ``rrls train`` makes) from the rest of the work.

Every measurement runs in a fresh process.

Target: (b) >= 2x (a). Measured after learning starts and ``--warmup`` updates (default 3 000:
enough for dead units' Adam moments to reach the denormal range, as in real training).

    python benchmarks/train_speed.py [--task hopper] [--steps 600] [--warmup 3000] [--rounds 3]
"""

from __future__ import annotations

import argparse
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
    if name in ("straightforward", "ftz"):
        if name == "ftz":
            torch.set_flush_denormal(True)
        return straightforward(task, steps, warmup)
    return rrls_algo(name, task, steps, warmup)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--task", default="hopper")
    parser.add_argument("--steps", type=int, default=600)
    parser.add_argument("--warmup", type=int, default=3000)
    parser.add_argument("--rounds", type=int, default=3)
    args = parser.parse_args()
    warnings.simplefilter("ignore")
    runs: dict[str, list[float]] = {k: [] for k in ("straightforward", "ftz", "td3", "m2td3")}
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
    print("| implementation | steps/s | ratio vs straightforward |")
    print("|---|---|---|")
    print(f"| (a) straightforward (CleanRL-style) | {med['straightforward']:.0f} | 1.00x |")
    print(
        f"| (a') (a) + flush denormals to zero | {med['ftz']:.0f} | "
        f"{med['ftz'] / med['straightforward']:.2f}x |"
    )
    print(f"| (b) rrls TD3 | {med['td3']:.0f} | {med['td3'] / med['straightforward']:.2f}x |")
    print(
        f"| (c) rrls M2TD3 (batch 100, 5 candidates) | {med['m2td3']:.0f} | "
        f"{med['m2td3'] / med['straightforward']:.2f}x |"
    )


if __name__ == "__main__":
    main()
