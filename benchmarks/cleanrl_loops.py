"""CleanRL's TD3 and SAC training loops, the references of ``train_speed.py``.

Transcribed from CleanRL (``cleanrl/td3_continuous_action.py`` and
``cleanrl/sac_continuous_action.py``, vwxyzjn/cleanrl): the same modules, optimisers, update
lines and per-step work, so a ratio against them prices rrls against the code most RL
researchers start from. Not used by rrls itself.

- ``cleanrl`` / ``cleanrl_sac``: the published loop, step for step: a one-env ``SyncVectorEnv``
  of ``gym.make`` + ``RecordEpisodeStatistics``, its replay buffer (``cleanrl_utils.buffers`` is
  Stable-Baselines3's ``ReplayBuffer``: 1 M preallocated numpy rows, a ``torch.tensor`` copy per
  field and batch; needs ``pip install -e .[bench]``), TensorBoard scalars every 100 steps.
  Changes for Gymnasium 1.x, none of them timed: the vector env resets in the step that ends an
  episode (``AutoresetMode.SAME_STEP``, the semantics the scripts were written for; 1.x's
  default would store a bogus transition per episode), whose final observation and episode
  statistics 1.x names ``final_obs`` and ``final_info`` (a dict of arrays, not a list of
  dicts); the ``print`` of steps/s is dropped.
- ``straightforward``: CleanRL's TD3 update in a lean loop (no vector env, a list replay).
"""

from __future__ import annotations

import tempfile
import time
from typing import Any

import gymnasium as gym
import numpy as np
import torch
import torch.nn.functional as F
from torch import nn

from rrls.agents.envs import task_env

__all__ = ["CleanRLSAC", "CleanRLTD3", "cleanrl", "cleanrl_sac", "straightforward"]


class QNetwork(nn.Module):
    """CleanRL's ``QNetwork`` / ``SoftQNetwork`` (the same module in both scripts)."""

    def __init__(self, obs_dim: int, act_dim: int) -> None:
        super().__init__()
        self.fc1 = nn.Linear(obs_dim + act_dim, 256)
        self.fc2 = nn.Linear(256, 256)
        self.fc3 = nn.Linear(256, 1)

    def forward(self, x: torch.Tensor, a: torch.Tensor) -> torch.Tensor:
        x = torch.cat([x, a], 1)
        return self.fc3(F.relu(self.fc2(F.relu(self.fc1(x)))))


class ActorNet(nn.Module):
    """TD3's deterministic actor."""

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


def soft_update(pairs: tuple[tuple[nn.Module, nn.Module], ...], tau: float) -> None:
    """CleanRL's Polyak step: a Python loop over parameters, two temporaries each."""
    for net, target in pairs:
        for param, target_param in zip(net.parameters(), target.parameters()):
            target_param.data.copy_(tau * param.data + (1 - tau) * target_param.data)


def critic_step(agent: Any, o, a, next_q_value: torch.Tensor) -> dict[str, Any]:
    """The twin critics' step, the same lines in both scripts: each ``Q_i(s, a)`` regressed on
    ``next_q_value`` (MSE), one Adam step of both; the values and losses CleanRL logs."""
    out: dict[str, Any] = {
        "qf1_values": agent.qf1(o, a).view(-1),
        "qf2_values": agent.qf2(o, a).view(-1),
    }
    out["qf1_loss"] = F.mse_loss(out["qf1_values"], next_q_value)
    out["qf2_loss"] = F.mse_loss(out["qf2_values"], next_q_value)
    out["qf_loss"] = out["qf1_loss"] + out["qf2_loss"]
    agent.q_optimizer.zero_grad()
    out["qf_loss"].backward()
    agent.q_optimizer.step()
    return out


class CleanRLTD3:
    """``td3_continuous_action.py``'s networks, optimisers and update lines."""

    def __init__(self, obs_dim: int, act_dim: int, low: np.ndarray, high: np.ndarray) -> None:
        self.low, self.high = float(low[0]), float(high[0])  # CleanRL clamps to scalar bounds
        self.actor = ActorNet(obs_dim, act_dim, (high - low) / 2, (high + low) / 2)
        self.qf1, self.qf2 = QNetwork(obs_dim, act_dim), QNetwork(obs_dim, act_dim)
        self.qf1_target, self.qf2_target = QNetwork(obs_dim, act_dim), QNetwork(obs_dim, act_dim)
        self.target_actor = ActorNet(obs_dim, act_dim, (high - low) / 2, (high + low) / 2)
        self.target_actor.load_state_dict(self.actor.state_dict())
        self.qf1_target.load_state_dict(self.qf1.state_dict())
        self.qf2_target.load_state_dict(self.qf2.state_dict())
        critic_params = list(self.qf1.parameters()) + list(self.qf2.parameters())
        self.q_optimizer = torch.optim.Adam(critic_params, lr=3e-4)
        self.actor_optimizer = torch.optim.Adam(list(self.actor.parameters()), lr=3e-4)

    def act(self, obs: np.ndarray) -> np.ndarray:
        with torch.no_grad():
            actions = self.actor(torch.Tensor(obs))
            actions += torch.normal(0, self.actor.action_scale * 0.1)
            return actions.cpu().numpy().clip(self.low, self.high)

    def update(self, o, a, r, no, d, step: int) -> dict[str, Any]:
        """One TD3 update on a batch of tensors, line for line as CleanRL writes it."""
        with torch.no_grad():
            clipped_noise = (torch.randn_like(a) * 0.2).clamp(
                -0.5, 0.5
            ) * self.target_actor.action_scale
            next_state_actions = (self.target_actor(no) + clipped_noise).clamp(self.low, self.high)
            qf1_next_target = self.qf1_target(no, next_state_actions)
            qf2_next_target = self.qf2_target(no, next_state_actions)
            min_qf_next_target = torch.min(qf1_next_target, qf2_next_target)
            next_q_value = r.flatten() + (1 - d.flatten()) * 0.99 * min_qf_next_target.view(-1)
        out = critic_step(self, o, a, next_q_value)
        if step % 2 == 0:
            out["actor_loss"] = -self.qf1(o, self.actor(o)).mean()
            self.actor_optimizer.zero_grad()
            out["actor_loss"].backward()
            self.actor_optimizer.step()
            soft_update(
                (
                    (self.actor, self.target_actor),
                    (self.qf1, self.qf1_target),
                    (self.qf2, self.qf2_target),
                ),
                0.005,
            )
        return out


LOG_STD_MAX, LOG_STD_MIN = 2, -5


class GaussianActorNet(nn.Module):
    """SAC's squashed Gaussian actor (``sac_continuous_action.py``'s ``Actor``)."""

    def __init__(self, obs_dim: int, act_dim: int, scale: np.ndarray, bias: np.ndarray) -> None:
        super().__init__()
        self.fc1 = nn.Linear(obs_dim, 256)
        self.fc2 = nn.Linear(256, 256)
        self.fc_mean = nn.Linear(256, act_dim)
        self.fc_logstd = nn.Linear(256, act_dim)
        self.register_buffer("action_scale", torch.tensor(scale, dtype=torch.float32))
        self.register_buffer("action_bias", torch.tensor(bias, dtype=torch.float32))

    def forward(self, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        x = F.relu(self.fc2(F.relu(self.fc1(x))))
        mean, log_std = self.fc_mean(x), torch.tanh(self.fc_logstd(x))
        return mean, LOG_STD_MIN + 0.5 * (LOG_STD_MAX - LOG_STD_MIN) * (log_std + 1)

    def get_action(self, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        mean, log_std = self(x)
        normal = torch.distributions.Normal(mean, log_std.exp())
        x_t = normal.rsample()
        y_t = torch.tanh(x_t)
        action = y_t * self.action_scale + self.action_bias
        log_prob = normal.log_prob(x_t)
        log_prob -= torch.log(self.action_scale * (1 - y_t.pow(2)) + 1e-6)
        log_prob = log_prob.sum(1, keepdim=True)
        return action, log_prob, torch.tanh(mean) * self.action_scale + self.action_bias


class CleanRLSAC:
    """``sac_continuous_action.py``'s networks, optimisers and update lines (its defaults:
    q_lr 1e-3, policy_lr 3e-4, policy_frequency 2 with as many policy steps, autotune)."""

    def __init__(self, obs_dim: int, act_dim: int, low: np.ndarray, high: np.ndarray) -> None:
        self.actor = GaussianActorNet(obs_dim, act_dim, (high - low) / 2, (high + low) / 2)
        self.qf1, self.qf2 = QNetwork(obs_dim, act_dim), QNetwork(obs_dim, act_dim)
        self.qf1_target, self.qf2_target = QNetwork(obs_dim, act_dim), QNetwork(obs_dim, act_dim)
        self.qf1_target.load_state_dict(self.qf1.state_dict())
        self.qf2_target.load_state_dict(self.qf2.state_dict())
        critic_params = list(self.qf1.parameters()) + list(self.qf2.parameters())
        self.q_optimizer = torch.optim.Adam(critic_params, lr=1e-3)
        self.actor_optimizer = torch.optim.Adam(list(self.actor.parameters()), lr=3e-4)
        self.target_entropy = -float(act_dim)
        self.log_alpha = torch.zeros(1, requires_grad=True)
        self.alpha = self.log_alpha.exp().item()
        self.a_optimizer = torch.optim.Adam([self.log_alpha], lr=1e-3)

    def act(self, obs: np.ndarray) -> np.ndarray:
        actions, _, _ = self.actor.get_action(torch.Tensor(obs))
        return actions.detach().cpu().numpy()

    def update(self, o, a, r, no, d, step: int) -> dict[str, Any]:
        """One SAC update on a batch of tensors, line for line as CleanRL writes it."""
        with torch.no_grad():
            next_state_actions, next_state_log_pi, _ = self.actor.get_action(no)
            qf1_next_target = self.qf1_target(no, next_state_actions)
            qf2_next_target = self.qf2_target(no, next_state_actions)
            min_qf_next_target = (
                torch.min(qf1_next_target, qf2_next_target) - self.alpha * next_state_log_pi
            )
            next_q_value = r.flatten() + (1 - d.flatten()) * 0.99 * min_qf_next_target.view(-1)
        out = critic_step(self, o, a, next_q_value)
        if step % 2 == 0:
            for _ in range(2):  # CleanRL compensates the delay with as many policy steps
                pi, log_pi, _ = self.actor.get_action(o)
                min_qf_pi = torch.min(self.qf1(o, pi), self.qf2(o, pi))
                out["actor_loss"] = ((self.alpha * log_pi) - min_qf_pi).mean()
                self.actor_optimizer.zero_grad()
                out["actor_loss"].backward()
                self.actor_optimizer.step()
                with torch.no_grad():
                    _, log_pi, _ = self.actor.get_action(o)
                out["alpha_loss"] = (-self.log_alpha.exp() * (log_pi + self.target_entropy)).mean()
                self.a_optimizer.zero_grad()
                out["alpha_loss"].backward()
                self.a_optimizer.step()
                self.alpha = self.log_alpha.exp().item()
        soft_update(((self.qf1, self.qf1_target), (self.qf2, self.qf2_target)), 0.005)
        out["alpha"] = self.alpha
        return out


def straightforward(task: str, steps: int, warmup: int, seed: int = 0) -> float:
    """CleanRL's TD3 update in a lean loop; env steps/s over ``steps`` steps after ``warmup``."""
    env = task_env(task)[0]
    obs_dim, act_dim = env.observation_space.shape[0], env.action_space.shape[0]
    low, high = env.action_space.low, env.action_space.high
    torch.manual_seed(seed)
    rng = np.random.default_rng(seed)
    td3 = CleanRLTD3(obs_dim, act_dim, low, high)
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
        action = td3.act(obs[None])[0]
        next_obs, reward, terminated, _, _ = env.step(action)
        buffer.append((obs, action, reward, next_obs, terminated))
        obs = next_obs if not terminated else env.reset()[0]

        idx = rng.integers(0, len(buffer), 256)
        o, a, r, no, d = (np.array(x) for x in zip(*(buffer[i] for i in idx)))
        o, a, no = torch.Tensor(o), torch.Tensor(a), torch.Tensor(no)
        r, d = torch.Tensor(r), torch.Tensor(d.astype(np.float32))
        td3.update(o, a, r, no, d, step)
    return steps / (time.perf_counter() - start)


#: the scalars each script logs every 100 steps (besides ``charts/SPS``)
LOGGED = {
    "td3": ("qf1_loss", "qf2_loss", "actor_loss"),
    "sac": ("qf1_loss", "qf2_loss", "actor_loss", "alpha", "alpha_loss"),
}


def published(
    algo: str,
    task: str,
    steps: int,
    warmup: int,
    seed: int = 0,
    learning_starts: int = 1000,
    returns: list[tuple[int, float]] | None = None,
) -> float:
    """CleanRL's ``{algo}_continuous_action.py`` loop as published, on this stack: env steps/s
    over ``steps`` steps after ``learning_starts`` random steps and ``warmup`` updates.
    ``returns``: each finished training episode's ``(global_step, return)`` is appended (what
    the script logs as ``charts/episodic_return``)."""
    from stable_baselines3.common.buffers import ReplayBuffer as SB3ReplayBuffer
    from torch.utils.tensorboard import SummaryWriter

    from rrls.tasks import get_task

    def thunk() -> gym.Env:
        env = gym.wrappers.RecordEpisodeStatistics(gym.make(get_task(task).v5_id))
        env.action_space.seed(seed)
        return env

    # the script's semantics (gym 0.29): the episode's last transition and its return are read
    # at the step that ends it (Gymnasium 1.x's default resets one step later)
    envs = gym.vector.SyncVectorEnv([thunk], autoreset_mode=gym.vector.AutoresetMode.SAME_STEP)
    obs_dim = envs.single_observation_space.shape[0]
    act_dim = envs.single_action_space.shape[0]
    low, high = envs.single_action_space.low, envs.single_action_space.high
    np.random.seed(seed)  # noqa: NPY002 - SB3's buffer (CleanRL's) samples from the global one
    torch.manual_seed(seed)
    agent = (CleanRLSAC if algo == "sac" else CleanRLTD3)(obs_dim, act_dim, low, high)
    envs.single_observation_space.dtype = np.float32
    rb = SB3ReplayBuffer(
        1_000_000,
        envs.single_observation_space,
        envs.single_action_space,
        "cpu",
        handle_timeout_termination=False,
    )
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
                actions = agent.act(obs)
            next_obs, rewards, terminations, truncations, infos = envs.step(actions)
            if "final_info" in infos and "episode" in infos["final_info"]:
                episode = infos["final_info"]["episode"]
                for idx in np.flatnonzero(infos["final_info"]["_episode"]):
                    writer.add_scalar("charts/episodic_return", episode["r"][idx], global_step)
                    if returns is not None:
                        returns.append((global_step, float(episode["r"][idx])))
                    break
            real_next_obs = next_obs.copy()
            for idx, trunc in enumerate(truncations):
                if trunc:
                    real_next_obs[idx] = infos["final_obs"][idx]
            rb.add(obs, real_next_obs, actions, rewards, terminations, infos)
            obs = next_obs
            if global_step > learning_starts:
                data = rb.sample(256)
                losses = agent.update(
                    data.observations,
                    data.actions,
                    data.rewards,
                    data.next_observations,
                    data.dones,
                    global_step,
                )
                if global_step % 100 == 0:
                    for name in ("qf1_values", "qf2_values"):
                        writer.add_scalar(f"losses/{name}", losses[name].mean().item(), global_step)
                    for name in LOGGED[algo]:
                        value = losses[name]
                        value = value.item() if isinstance(value, torch.Tensor) else value
                        writer.add_scalar(f"losses/{name}", value, global_step)
                    writer.add_scalar("losses/qf_loss", losses["qf_loss"].item() / 2.0, global_step)
                    writer.add_scalar("charts/SPS", global_step, global_step)
        elapsed = time.perf_counter() - start
        writer.close()
    envs.close()
    return steps / elapsed


def cleanrl(task: str, steps: int, warmup: int, seed: int = 0) -> float:
    """CleanRL's ``td3_continuous_action.py`` loop (``published``)."""
    return published("td3", task, steps, warmup, seed)


def cleanrl_sac(task: str, steps: int, warmup: int, seed: int = 0) -> float:
    """CleanRL's ``sac_continuous_action.py`` loop (``published``)."""
    return published("sac", task, steps, warmup, seed)
