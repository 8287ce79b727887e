"""TD3 (Fujimoto, van Hoof, Meger 2018, "Addressing Function Approximation Error in Actor-Critic
Methods"; https://arxiv.org/abs/1802.09477). CleanRL's ``td3_continuous_action.py``, for a group
of ``K`` runs.

The paper's non-robust baseline: trained on the nominal task, only evaluated over the
uncertainty set. Twin critics regressed on ``y = r + γ (1 - terminated) min_i Q_i'(s', ã')``
with ``ã' = clip(π'(s') + clip(σ ε, -c, c) · scale, low, high)``; every ``policy_frequency``
updates the actor ascends ``Q_1(s, π(s))`` and the targets move by Polyak averaging. Acting:
``π(s) + N(0, exploration_noise · scale)``, clipped (the loop does the uniform warm-up).

``TD3`` (the networks, optimisers and losses) is reused by DR, RARL, NR-MDP and M2TD3.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass
from typing import Any

import numpy as np
import torch

from rrls.agents.envs import task_env
from rrls.agents.graphs import Update, adam, descend, load_optimizer
from rrls.agents.hparams import MAX_BATCH, MAX_BUFFER, MAX_LAYERS, MAX_WIDTH, check_limits, hp
from rrls.agents.learner import DeviceActing
from rrls.agents.learner import Learner as _Learner
from rrls.agents.nets import Actor, Critic, NumpyActor, deterministic, polyak, to_mlp_policy
from rrls.agents.replay import ReplayBuffer, transition_fields
from rrls.agents.streams import Generators, NumpyGenerators, RunSeeds
from rrls.algorithms import warmup


@dataclass
class Config:
    """The paper's TD3 hyper-parameters (RRLS Table "hyperparameters_td3" = CleanRL's)."""

    learning_rate: float = hp(3e-4, "Adam step size of actors and critics")
    gamma: float = hp(0.99, "discount factor")
    tau: float = hp(0.005, "Polyak rate of the target networks")
    policy_noise: float = hp(0.2, "target policy smoothing noise (times the action scale)")
    noise_clip: float = hp(0.5, "clip of the smoothing noise (times the action scale)")
    exploration_noise: float = hp(0.1, "Gaussian exploration noise (times the action scale)")
    learning_starts: int = hp(warmup("td3"), "uniformly random steps before learning starts")
    policy_frequency: int = hp(2, "critic updates per actor update (TD3's delay)")
    batch_size: int = hp(256, "replay batch size", most=MAX_BATCH)
    buffer_size: int = hp(1_000_000, "replay capacity (transitions)", most=MAX_BUFFER)
    hidden: tuple[int, ...] = hp(
        (256, 256),
        "hidden layer sizes of actors and critics",
        most=MAX_WIDTH,
        most_items=MAX_LAYERS,
    )

    def __post_init__(self) -> None:
        self.hidden = tuple(int(h) for h in self.hidden)
        check_limits(self)
        for name in ("learning_rate", "tau", "policy_frequency", "batch_size", "buffer_size"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value > 0):
                raise ValueError(f"{name} must be a positive number, got {value}")
        for name in ("policy_noise", "noise_clip", "exploration_noise", "learning_starts"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value >= 0):
                raise ValueError(f"{name} must be >= 0, got {value}")
        if not 0 <= self.gamma <= 1:
            raise ValueError(f"gamma must be in [0, 1], got {self.gamma}")
        if self.tau > 1:
            raise ValueError(f"tau must be in (0, 1], got {self.tau}")
        if not self.hidden or min(self.hidden) < 1:
            raise ValueError(f"hidden layer sizes must be >= 1, got {list(self.hidden)}")


TD3Config = Config  # the name the other algorithms extend


def make_env(task: str, uncertainty: Any, config: Config, paper: bool = False) -> Any:
    """The nominal task: TD3 never sees the uncertainty set (it is only evaluated over it)."""
    return task_env(task, paper=paper)[0]


def cat(*parts: torch.Tensor | None) -> torch.Tensor:
    return torch.cat([p for p in parts if p is not None], dim=-1)


class TD3:
    """``K`` runs' actor, twin critic, their targets and Adam optimisers, and TD3's losses.

    ``cond_dim``: critics also see a condition (M2TD3's ω). ``name`` keeps the generators of
    several players of one run apart (``"init"``, ``"adversary.init"``).
    """

    def __init__(
        self,
        obs_dim: int,
        low: np.ndarray,
        high: np.ndarray,
        config: Config,
        seeds: list[RunSeeds],
        device: torch.device,
        cond_dim: int = 0,
        name: str = "",
    ) -> None:
        act_dim = len(low)
        init = Generators(seeds, name + "init")
        self.config, self.device = config, torch.device(device)
        self.actor = Actor(obs_dim, act_dim, config.hidden, low, high, init).to(device)
        self.critic = Critic(obs_dim + act_dim + cond_dim, config.hidden, init).to(device)
        self.actor_target = copy.deepcopy(self.actor).requires_grad_(False)
        self.critic_target = copy.deepcopy(self.critic).requires_grad_(False)
        self.actor_opt = adam(self.actor.parameters(), config.learning_rate, device)
        self.critic_opt = adam(self.critic.parameters(), config.learning_rate, device)
        self.targets = [*self.actor_target.parameters(), *self.critic_target.parameters()]
        self.sources = [*self.actor.parameters(), *self.critic.parameters()]
        self.noise = Generators(seeds, name + "noise")  # target policy smoothing
        self.seeds, self.name = seeds, name
        self.ahead: NumpyGenerators | None = None  # draw_ahead's streams, made on first use
        self.low = torch.as_tensor(np.asarray(low, np.float32), device=device)
        self.high = torch.as_tensor(np.asarray(high, np.float32), device=device)
        self.act_dim = act_dim
        self.fast = NumpyActor(self.actor) if self.device.type == "cpu" else None

    def act(self, obs: np.ndarray) -> np.ndarray:
        """Each run's ``π(s)`` for its own observation, ``(K, obs) -> (K, act)``."""
        return deterministic(self.actor, obs, self.fast)

    def draw(self, batch: int, width: int | None = None) -> torch.Tensor:
        """Standard normal ``(K, batch, width)``, each run from its own generator."""
        width = self.act_dim if width is None else width
        return torch.stack([torch.randn((batch, width), generator=g) for g in self.noise])

    def draw_ahead(self, steps: int, batch: int) -> torch.Tensor:
        """``draw``'s noise for the next ``steps`` updates, ``(steps, K, batch, act)`` on the
        device, from each run's ``"noise.ahead"`` numpy stream (the device-resident loop)."""
        if self.ahead is None:
            self.ahead = NumpyGenerators(self.seeds, self.name + "noise.ahead")
        shape = (steps, batch, self.act_dim)
        eps = [rng.standard_normal(shape, dtype=np.float32) for rng in self.ahead]
        return torch.from_numpy(np.stack(eps, 1)).to(self.device)

    @torch.no_grad()
    def target_action(self, actor: Actor, next_obs: torch.Tensor, eps: torch.Tensor):
        """``clip(π'(s') + clip(σ ε, -c, c) · scale, low, high)`` (target policy smoothing)."""
        cfg = self.config
        noise = (eps * cfg.policy_noise).clamp(-cfg.noise_clip, cfg.noise_clip)
        return (actor(next_obs) + noise * actor.action_scale).clamp(self.low, self.high)

    @torch.no_grad()
    def target(self, data: dict[str, torch.Tensor], q_next: torch.Tensor) -> torch.Tensor:
        """``r + γ (1 - terminated) q'``; truncated transitions have ``terminated = 0``."""
        return data["reward"] + self.config.gamma * (1.0 - data["terminated"]) * q_next

    def td_target(self, data, eps, next_cond=None) -> torch.Tensor:
        """TD3's target ``r + γ (1 - d) min_i Q_i'(s', ã')``, ``(K, B)``."""
        next_action = self.target_action(self.actor_target, data["next_obs"], eps)
        with torch.no_grad():
            q_next = self.critic_target(cat(data["next_obs"], next_action, next_cond)).amin(1)
        return self.target(data, q_next)

    def critic_step(self, obs, action, y, cond=None) -> torch.Tensor:
        """One Adam step on ``Σ_i mean((Q_i(s, a) - y)²)`` per run (CleanRL's
        ``qf1_loss + qf2_loss``); returns the ``(K,)`` losses."""
        q = self.critic(cat(obs, action, cond))
        loss = (q - y.unsqueeze(1)).square().mean(-1).sum(-1)
        descend(self.critic_opt, loss)  # runs do not mix: each run's gradient is its own loss's
        return loss.detach()

    def policy_step(self, actor: Actor, opt, loss: torch.Tensor) -> torch.Tensor:
        """One Adam step of ``actor`` on ``loss`` (``(K,)``), gradients into ``actor`` only."""
        descend(opt, loss, only=True)
        return loss.detach()

    def actor_step(self, obs, cond=None) -> torch.Tensor:
        """One Adam step on ``-mean Q_1(s, π(s))``."""
        loss = -self.critic.q1(cat(obs, self.actor(obs), cond)).mean(-1)
        return self.policy_step(self.actor, self.actor_opt, loss)

    def soft_update(self) -> None:
        polyak(self.targets, self.sources, self.config.tau)

    def state_dict(self) -> dict[str, Any]:
        return {
            **{n: getattr(self, n).state_dict() for n in NETS},
            "noise": self.noise.state_dict(),
            **({"noise_ahead": self.ahead.state_dict()} if self.ahead is not None else {}),
        }

    def load_state_dict(self, state: dict[str, Any]) -> None:
        for n in NETS:
            if n.endswith("_opt"):
                load_optimizer(getattr(self, n), state[n])
            else:
                getattr(self, n).load_state_dict(state[n])
        self.noise.load_state_dict(state["noise"])
        if "noise_ahead" in state:
            self.ahead = NumpyGenerators(self.seeds, self.name + "noise.ahead")
            self.ahead.load_state_dict(state["noise_ahead"])


NETS = ("actor", "actor_target", "critic", "critic_target", "actor_opt", "critic_opt")


class Learner(DeviceActing, _Learner):
    """TD3 for ``K`` runs: one replay buffer each, one update for all."""

    def __init__(self, env: Any, config: Config, seeds: list[RunSeeds], device: Any) -> None:
        obs_dim = env.observation_space.shape[0]
        self.low, self.high = env.action_space.low, env.action_space.high
        self.config = config
        self.agent = TD3(obs_dim, self.low, self.high, config, seeds, device)
        self.rngs = NumpyGenerators(seeds, "explore")
        self.sigma = (self.high - self.low) / 2 * config.exploration_noise
        self.buffer = ReplayBuffer(
            config.buffer_size, transition_fields(obs_dim, (len(self.low),)), device, seeds
        )
        self._update = Update(self._compute, device)

    def act(self, obs: np.ndarray) -> list[Any]:
        """``π(s) + N(0, σ · scale)`` per run (each run's own generator), clipped to the box."""
        return list(np.clip(self.explore(obs), self.low, self.high).astype(np.float32))

    def explore(self, obs: np.ndarray) -> np.ndarray:
        """``π(s) + N(0, σ · scale)`` per run, unclipped (each run's own generator)."""
        noise = np.stack([rng.normal(0.0, self.sigma) for rng in self.rngs])
        return self.agent.act(obs) + noise

    def observe(self, obs, actions, rewards, next_obs, terminated, infos) -> None:
        self.buffer.add(
            obs=obs, action=actions, reward=rewards, next_obs=next_obs, terminated=terminated
        )

    def update(self, step: int) -> dict[str, torch.Tensor]:
        size = self.config.batch_size
        draws = {"idx": self.buffer.draw(size), "eps": self.agent.draw(size)}
        return self.update_drawn(step, draws)

    def update_drawn(self, step: int, draws: dict[str, torch.Tensor]) -> dict[str, torch.Tensor]:
        """The update of ``step`` on given random inputs (``idx``, ``eps``)."""
        return self._update(step % self.config.policy_frequency == 0, draws)

    # -- the device-resident loop (``rrls.agents.on_twin``): acting, storing and updating on
    # device tensors, every random input drawn a block of steps ahead (``docs/algorithms.md``)
    def draw_ahead(self, steps: int) -> dict[str, torch.Tensor]:
        """The next ``steps`` env steps' random inputs, ``(steps, K, ...)`` on the device:
        exploration noise from the runs' ``"explore"`` streams (the CPU path's draws), replay
        indices and smoothing noise from their ``".ahead"`` streams."""
        size = self.config.batch_size
        noise = np.stack(
            [rng.normal(0.0, self.sigma, (steps, len(self.sigma))) for rng in self.rngs], 1
        )
        return {
            "noise": torch.from_numpy(noise.astype(np.float32)).to(self.agent.device),
            "idx": self.buffer.draw_ahead(steps, size),
            "eps": self.agent.draw_ahead(steps, size),
        }

    def _act_on_device(self, _variant: None, x: dict[str, torch.Tensor]) -> torch.Tensor:
        """``act_tensor``'s device work: ``clip(π(s) + noise, low, high)``."""
        with torch.no_grad():
            action = self.agent.actor(x["obs"].unsqueeze(1)).squeeze(1) + x["noise"]
            return action.clamp(self.agent.low, self.agent.high)

    def _compute(self, update_actor: bool, x: dict[str, torch.Tensor]) -> dict[str, torch.Tensor]:
        """The device work of one update (``graphs.Update`` may capture it)."""
        agent, data = self.agent, self.buffer.gather(x["idx"])
        y = agent.td_target(data, x["eps"])
        losses = {"critic_loss": agent.critic_step(data["obs"], data["action"], y)}
        if update_actor:
            losses["actor_loss"] = agent.actor_step(data["obs"])
            agent.soft_update()
        return losses

    def state_dict(self) -> dict[str, Any]:
        return {
            "agent": self.agent.state_dict(),
            "explore": self.rngs.state_dict(),
            "buffer": self.buffer.state_dict(),
        }

    def load_state_dict(self, state: dict[str, Any]) -> None:
        self.agent.load_state_dict(state["agent"])
        self.rngs.load_state_dict(state["explore"])
        self.buffer.load_state_dict(state["buffer"])

    def export(self, k: int) -> dict[str, Any]:
        return {"policy": to_mlp_policy(self.agent.actor, k)}
