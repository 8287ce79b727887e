"""SAC (Haarnoja et al. 2018, "Soft Actor-Critic Algorithms and Applications";
https://arxiv.org/abs/1812.05905). CleanRL's ``sac_continuous_action.py`` and its
hyper-parameters, for a group of ``K`` runs. Not part of the paper's five baselines: trained on
the nominal task and evaluated over the uncertainty set like TD3.

- Critics: ``y = r + γ (1 - terminated) (min_i Q_i'(s', a') - α log π(a'|s'))``, ``a' ~ π(s')``;
  loss ``Σ_i mean((Q_i(s, a) - y)²)``.
- Actor, every ``policy_frequency`` updates, as many steps (CleanRL's delayed update):
  ``mean(α log π(ã|s) - min_i Q_i(s, ã))``, ``ã ~ π(s)`` reparameterised.
- Temperature (``autotune``): ``log α`` descends ``-α (log π(ã|s) + H̄)``, ``H̄ = -dim(A)``,
  from ``log α = 0`` (α₀ = 1), as CleanRL (``sac_continuous_action.py:205``, ``log_alpha =
  torch.zeros(1)``); without ``autotune`` α stays at ``entropy_coef`` (CleanRL's ``alpha``,
  0.2, used only then: ``:63``, ``:209``).
- Targets: Polyak averaging every ``target_network_frequency`` updates.
- Acting: a sample of the squashed Gaussian policy (the loop does the uniform warm-up); the
  exported policy for evaluation is its mean, ``tanh(μ(s))`` scaled to the box.
"""

from __future__ import annotations

import copy
import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import torch

from rrls.agents.envs import task_env
from rrls.agents.graphs import Update, adam, descend, load_optimizer
from rrls.agents.hparams import MAX_BATCH, MAX_BUFFER, MAX_LAYERS, MAX_WIDTH, check_limits, hp
from rrls.agents.learner import DeviceActing
from rrls.agents.learner import Learner as _Learner
from rrls.agents.nets import Critic, GaussianActor, polyak, to_mlp_policy
from rrls.agents.replay import ReplayBuffer, transition_fields
from rrls.agents.streams import Generators, NumpyGenerators, RunSeeds
from rrls.algorithms import warmup


@dataclass
class Config:
    """CleanRL's ``sac_continuous_action.py`` defaults."""

    policy_lr: float = hp(3e-4, "Adam step size of the policy")
    q_lr: float = hp(1e-3, "Adam step size of the critics (and of the temperature)")
    gamma: float = hp(0.99, "discount factor")
    tau: float = hp(0.005, "Polyak rate of the target networks")
    learning_starts: int = hp(warmup("sac"), "uniformly random steps before learning starts")
    policy_frequency: int = hp(2, "critic updates per (burst of) policy updates")
    target_network_frequency: int = hp(1, "critic updates per Polyak step")
    entropy_coef: float = hp(
        0.2, "SAC's temperature α with --no-autotune (autotuned runs start at α = 1, as CleanRL)"
    )
    autotune: bool = hp(True, "learn α towards the target entropy -dim(A)")
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
        for name in (
            "policy_lr",
            "q_lr",
            "tau",
            "policy_frequency",
            "target_network_frequency",
            "entropy_coef",
            "batch_size",
            "buffer_size",
        ):
            value = getattr(self, name)
            if not (np.isfinite(value) and value > 0):
                raise ValueError(f"{name} must be a positive number, got {value}")
        if not 0 <= self.gamma <= 1:
            raise ValueError(f"gamma must be in [0, 1], got {self.gamma}")
        if self.learning_starts < 0:
            raise ValueError(f"learning_starts must be >= 0, got {self.learning_starts}")
        if not self.hidden or min(self.hidden) < 1:
            raise ValueError(f"hidden layer sizes must be >= 1, got {list(self.hidden)}")


def make_env(task: str, uncertainty: Any, config: Config, paper: bool = False) -> Any:
    """The nominal task (SAC never sees the uncertainty set; it is only evaluated over it)."""
    return task_env(task, paper=paper)[0]


class Learner(DeviceActing, _Learner):
    """SAC for ``K`` runs: one replay buffer each, one update for all."""

    def __init__(self, env: Any, config: Config, seeds: list[RunSeeds], device: Any) -> None:
        obs_dim = env.observation_space.shape[0]
        self.low, self.high = env.action_space.low, env.action_space.high
        act_dim, hidden = len(self.low), config.hidden
        self.config, self.device = config, torch.device(device)
        init = Generators(seeds, "init")
        self.actor = GaussianActor(obs_dim, act_dim, hidden, self.low, self.high, init).to(device)
        self.critic = Critic(obs_dim + act_dim, hidden, init).to(device)
        self.critic_target = copy.deepcopy(self.critic).requires_grad_(False)
        self.actor_opt = adam(self.actor.parameters(), config.policy_lr, device)
        self.critic_opt = adam(self.critic.parameters(), config.q_lr, device)
        self.targets, self.sources = [*self.critic_target.parameters()], [*self.critic.parameters()]
        # CleanRL: autotuned from log α = 0 (α₀ = 1); the fixed α only without autotune
        start = 0.0 if config.autotune else math.log(config.entropy_coef)
        self.log_alpha = torch.full((len(seeds),), start, device=device, requires_grad=True)
        self.alpha_opt = adam([self.log_alpha], config.q_lr, device)
        self.target_entropy = -float(act_dim)
        self.noise = Generators(seeds, "noise")  # the updates' action samples
        self.rngs = NumpyGenerators(seeds, "explore")  # acting's samples
        self.buffer = ReplayBuffer(
            config.buffer_size, transition_fields(obs_dim, (act_dim,)), device, seeds
        )
        self.act_dim = act_dim
        self._update = Update(self._compute, device)
        self.seeds = seeds
        self.ahead: NumpyGenerators | None = None  # draw_ahead's streams, made on first use

    def act(self, obs: np.ndarray) -> list[Any]:
        """A sample of each run's policy at its observation."""
        eps = np.stack([rng.standard_normal(self.act_dim) for rng in self.rngs])
        with torch.inference_mode():
            x = torch.as_tensor(np.asarray(obs), dtype=torch.float32, device=self.device)
            e = torch.as_tensor(eps, dtype=torch.float32, device=self.device)
            action, _ = self.actor.sample(x.unsqueeze(1), e.unsqueeze(1))
        return list(action.squeeze(1).cpu().numpy())

    def observe(self, obs, actions, rewards, next_obs, terminated, infos) -> None:
        self.buffer.add(
            obs=obs, action=actions, reward=rewards, next_obs=next_obs, terminated=terminated
        )

    def draw(self, batch: int, n: int) -> torch.Tensor:
        """``n`` standard normal ``(K, batch, act)`` draws, each run from its own generator."""
        shape = (n, batch, self.act_dim)
        return torch.stack([torch.randn(shape, generator=g) for g in self.noise], dim=1)

    def update(self, step: int) -> dict[str, torch.Tensor]:
        cfg = self.config
        n = 1 + (2 * cfg.policy_frequency if step % cfg.policy_frequency == 0 else 0)
        draws = {"idx": self.buffer.draw(cfg.batch_size), "eps": self.draw(cfg.batch_size, n)}
        return self.update_drawn(step, draws)

    def update_drawn(self, step: int, draws: dict[str, torch.Tensor]) -> dict[str, torch.Tensor]:
        """The update of ``step`` on ``draw_ahead``'s inputs of that step (its first ``n``
        noise samples: 1, or ``1 + 2 · policy_frequency`` with the policy steps)."""
        cfg = self.config
        policy = step % cfg.policy_frequency == 0
        target = step % cfg.target_network_frequency == 0
        n = 1 + (2 * cfg.policy_frequency if policy else 0)
        return self._update((policy, target), {"idx": draws["idx"], "eps": draws["eps"][:n]})

    # -- the device-resident loop (``rrls.agents.on_twin``): acting, storing and updating on
    # device tensors, every random input drawn a block of steps ahead (``docs/algorithms.md``)
    def draw_ahead(self, steps: int) -> dict[str, torch.Tensor]:
        """The next ``steps`` env steps' random inputs, ``(steps, ...)`` on the device: acting's
        samples from the runs' ``"explore"`` streams (the CPU path's draws), replay indices and
        the updates' samples (as many as an update with policy steps takes) from their
        ``".ahead"`` streams."""
        cfg = self.config
        if self.ahead is None:
            self.ahead = NumpyGenerators(self.seeds, "noise.ahead")
        n = 1 + 2 * cfg.policy_frequency
        shape = (steps, n, cfg.batch_size, self.act_dim)
        eps = [rng.standard_normal(shape, dtype=np.float32) for rng in self.ahead]
        noise = [rng.standard_normal((steps, self.act_dim)) for rng in self.rngs]
        return {
            "noise": torch.from_numpy(np.stack(noise, 1).astype(np.float32)).to(self.device),
            "idx": self.buffer.draw_ahead(steps, cfg.batch_size),
            "eps": torch.from_numpy(np.stack(eps, 2)).to(self.device),
        }

    def _act_on_device(self, _variant: None, x: dict[str, torch.Tensor]) -> torch.Tensor:
        """``act_tensor``'s device work: a sample of each run's policy, ``noise`` its ε."""
        with torch.no_grad():
            action, _ = self.actor.sample(x["obs"].unsqueeze(1), x["noise"].unsqueeze(1))
            return action.squeeze(1)

    def _compute(self, variant: tuple[bool, bool], x: dict[str, torch.Tensor]) -> dict:
        """The device work of one update (``graphs.Update`` may capture it)."""
        cfg, (policy, target) = self.config, variant
        data, eps = self.buffer.gather(x["idx"]), x["eps"]
        obs, alpha = data["obs"], self.log_alpha.detach().exp().unsqueeze(1)
        with torch.no_grad():
            next_action, next_log_pi = self.actor.sample(data["next_obs"], eps[0])
            q_next = self.critic_target(torch.cat((data["next_obs"], next_action), -1)).amin(1)
            soft = q_next - alpha * next_log_pi
            y = data["reward"] + cfg.gamma * (1.0 - data["terminated"]) * soft
        q = self.critic(torch.cat((obs, data["action"]), -1))
        critic_loss = (q - y.unsqueeze(1)).square().mean(-1).sum(-1)
        descend(self.critic_opt, critic_loss)  # runs do not mix: each run's gradient is its own
        # the policy steps' loop is a graph break: nothing of this frame may be on the stack
        # across it (``losses.update(...)`` held a fresh bound method there, which made dynamo
        # recompile the rest of the frame at every update until its limit)
        policy_losses = self._policy_steps(obs, eps) if policy else {}
        if target:
            polyak(self.targets, self.sources, cfg.tau)
        return {"critic_loss": critic_loss.detach(), **policy_losses}

    def _policy_steps(self, obs: torch.Tensor, eps: torch.Tensor) -> dict[str, torch.Tensor]:
        """CleanRL's delayed policy update: ``policy_frequency`` steps, the last one's losses.
        A loop of its own: ``torch.compile`` runs a loop holding a graph break (``backward``)
        eagerly, and compiles each step it calls."""
        losses: dict[str, torch.Tensor] = {}
        for i in range(self.config.policy_frequency):
            losses = self._policy_step(obs, eps[1 + 2 * i], eps[2 + 2 * i])
        return losses

    def _policy_step(self, obs, eps_actor, eps_alpha) -> dict[str, torch.Tensor]:
        """One policy step and, with ``autotune``, one temperature step."""
        alpha = self.log_alpha.detach().exp().unsqueeze(1)
        action, log_pi = self.actor.sample(obs, eps_actor)
        min_q = self.critic(torch.cat((obs, action), -1)).amin(1)
        actor_loss = (alpha * log_pi - min_q).mean(-1)
        descend(self.actor_opt, actor_loss, only=True)
        losses = {"actor_loss": actor_loss.detach()}
        if self.config.autotune:
            with torch.no_grad():
                _, log_pi = self.actor.sample(obs, eps_alpha)
            alpha_loss = -self.log_alpha.exp().unsqueeze(1) * (log_pi + self.target_entropy)
            alpha_loss = alpha_loss.mean(-1)
            descend(self.alpha_opt, alpha_loss)
            losses["alpha_loss"] = alpha_loss.detach()
        losses["alpha"] = self.log_alpha.detach().exp()
        return losses

    def state_dict(self) -> dict[str, Any]:
        return {
            **{n: getattr(self, n).state_dict() for n in NETS},
            "log_alpha": self.log_alpha.detach().clone(),
            "noise": self.noise.state_dict(),
            "explore": self.rngs.state_dict(),
            "buffer": self.buffer.state_dict(),
            **({"noise_ahead": self.ahead.state_dict()} if self.ahead is not None else {}),
        }

    def load_state_dict(self, state: dict[str, Any]) -> None:
        for n in NETS:
            if n.endswith("_opt"):
                load_optimizer(getattr(self, n), state[n])
            else:
                getattr(self, n).load_state_dict(state[n])
        with torch.no_grad():
            self.log_alpha.copy_(state["log_alpha"])
        self.noise.load_state_dict(state["noise"])
        self.rngs.load_state_dict(state["explore"])
        self.buffer.load_state_dict(state["buffer"])
        if "noise_ahead" in state:
            self.ahead = NumpyGenerators(self.seeds, "noise.ahead")
            self.ahead.load_state_dict(state["noise_ahead"])

    def export(self, k: int) -> dict[str, Any]:
        return {"policy": to_mlp_policy(self.actor, k)}


NETS = ("actor", "critic", "critic_target", "actor_opt", "critic_opt", "alpha_opt")
