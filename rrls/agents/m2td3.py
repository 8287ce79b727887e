"""M2TD3 (Tanabe et al. 2022, "Max-Min Off-Policy Actor-Critic Method Focusing on Worst-Case
Robustness to Model Misspecification"), on the TD3 core, following the authors' code
(github.com/akimotolab/M2TD3) and the paper's M2TD3 table.

- Critics ``Q(s, a, ω)`` take the uncertainty parameters ω (raw values, as the authors do).
- ``N = 5`` candidate worst-case parameters ω̂ₖ, each ``low + sigmoid(θₖ) (high - low)`` so they
  stay inside the box, initialised uniformly, each with its own Adam (``hatomega_learning_rate``
  3e-4: the paper's table lists it apart from the policy's rate, and the authors' code has its
  own key ``ho_lr``, so ``--learning-rate`` does not move it; ``--omega-learning-rate`` does).
- Every ``policy_frequency`` steps: the ω̂ₖ with the lowest ``mean Q1(s, π(s), ω̂ₖ)`` is the
  current worst; it takes an Adam step *down* ``Q1(s, π(s), ω̂ₖ)``, the policy a step *up*
  ``Q1(s, π(s), ω̂ₖ)`` (ω̂ₖ as it was before its step), and the selection probabilities move
  ``p ← (1 - 1/L) p + (1/L) e_k`` with ``L`` the last episode's length (a decaying average).
- Each episode: a candidate closer than 0.1 (L1, parameter units) to another, or whose
  probability fell below 0.05, is re-initialised (its probability set to the mean of the others);
  then ω̂ₖ is drawn with probabilities ``p`` and the episode runs at
  ``clip(ω̂ₖ + N(0, (1.0 · half-range)²), box)``. During the first ``learning_starts`` steps ω and
  the actions are uniform.
- Target smoothing on ω as on actions: ``ω' = clip(ω + clip(N(0, 0.2·half)², ±0.5·half), box)``.
- Batch 100 (the table), otherwise TD3's values.

Where the table is silent we follow the authors' code: ω̂ are re-initialised and drawn once per
episode; the omega std stays at ``omega_std_rate`` (their code defines a linear decay towards
``min_omega_std_rate`` but never calls it). Deliberate differences: the authors store
time-limit truncations as terminal, here truncated transitions bootstrap, as in our TD3; the
authors' random warm-up is ``start_steps`` = 100 k steps, here TD3's table value 25 k (the RRLS
table gives none for M2TD3; ``--learning-starts 100000`` restores theirs).

Opt-in (``normalize_omega`` / ``--normalize-omega``): the critics see ω rescaled to [-1, 1]. The
authors feed raw values; on InvertedPendulum's pole mass (1-31) raw ω swamps the first layer and
M2TD3 barely learns in 20 k steps (average 51 over the 1D mesh, seed 1), rescaled it learns as
fast as DR (average 879). The same function class — only the optimisation's conditioning changes.
"""

from __future__ import annotations

from dataclasses import dataclass
from itertools import combinations
from typing import Any

import numpy as np
import torch

from rrls.agents import td3
from rrls.agents.common import TrainConfig, task_env
from rrls.agents.core import TD3, TD3Config, hp
from rrls.agents.loop import Learner as _Learner
from rrls.agents.replay import ReplayBuffer, transition_fields


@dataclass
class Config(TD3Config):
    """The paper's M2TD3 table (``hyperparameters_m2td3``) on top of TD3's."""

    batch_size: int = hp(100, "replay batch size (M2TD3's table: 100)")
    hatomega_number: int = hp(5, "candidate worst-case parameters ω̂")
    hatomega_learning_rate: float = hp(3e-4, "Adam step size of the ω̂ (the table's own rate)")
    hatomega_parameter_distance: float = hp(0.1, "restart a ω̂ this close (L1) to another")
    minimum_probability: float = hp(0.05, "restart a ω̂ whose probability falls below this")
    omega_std_rate: float = hp(1.0, "ω exploration noise, times the set's half-range")
    policy_noise_rate: float = hp(0.2, "target smoothing noise on ω, times the half-range")
    noise_clip_omega_rate: float = hp(0.5, "clip of that noise, times the half-range")
    normalize_omega: bool = hp(
        False, "critics see ω rescaled to [-1, 1] (the authors feed raw values)"
    )

    def __post_init__(self) -> None:
        super().__post_init__()
        if self.hatomega_number < 2:
            raise ValueError(f"hatomega_number must be >= 2, got {self.hatomega_number}")
        lr = self.hatomega_learning_rate
        if not (np.isfinite(lr) and lr > 0):
            raise ValueError(f"hatomega_learning_rate must be a positive number, got {lr}")


class Candidates(torch.nn.Module):
    """The N candidate worst-case parameters ω̂, always inside ``[low, high]``."""

    def __init__(
        self,
        low: np.ndarray,
        high: np.ndarray,
        rng: np.random.Generator,
        n: int = 5,
        learning_rate: float = 3e-4,
        distance: float = 0.1,
        min_probability: float = 0.05,
    ) -> None:
        super().__init__()
        self.n, self.learning_rate = n, learning_rate
        self.distance, self.min_probability = distance, min_probability
        self.register_buffer("low", torch.tensor(np.array(low), dtype=torch.float32))
        self.register_buffer("high", torch.tensor(np.array(high), dtype=torch.float32))
        self.logits = torch.nn.ParameterList(
            torch.nn.Parameter(torch.zeros(len(low))) for _ in range(self.n)
        )
        self.optimizers = [torch.optim.Adam([p], lr=self.learning_rate) for p in self.logits]
        self.probabilities = np.full(self.n, 1.0 / self.n)
        for k in range(self.n):
            self.reinitialise(k, rng, probability=False)

    def value(self, k: int) -> torch.Tensor:
        return self.low + torch.sigmoid(self.logits[k]) * (self.high - self.low)

    def values(self) -> torch.Tensor:
        """All candidates as an ``(N, dim)`` tensor (no gradient)."""
        with torch.no_grad():
            return torch.stack([self.value(k) for k in range(self.n)])

    def reinitialise(self, k: int, rng: np.random.Generator, probability: bool = True) -> None:
        """A fresh uniform point and a fresh Adam; its probability = the mean of the others."""
        low, high = self.low.cpu().numpy(), self.high.cpu().numpy()
        y = (rng.uniform(low, high) - low) / np.maximum(high - low, 1e-5)
        y = np.clip(y, 1e-5, 1 - 1e-5)
        with torch.no_grad():
            self.logits[k].copy_(torch.as_tensor(np.log(y / (1 - y)), dtype=torch.float32))
        self.optimizers[k] = torch.optim.Adam([self.logits[k]], lr=self.learning_rate)
        if probability:
            self.probabilities[k] = 0.0
            self.probabilities[k] = self.probabilities.sum() / (self.n - 1)

    def restart(self, rng: np.random.Generator) -> list[int]:
        """Re-initialise candidates that collapsed onto another or are rarely the worst."""
        values = self.values().cpu().numpy()
        close = {
            i
            for i, j in combinations(range(self.n), 2)
            if np.abs(values[i] - values[j]).sum() <= self.distance
        }
        for k in sorted(close):
            self.reinitialise(k, rng)
        rare = [k for k in range(self.n) if self.probabilities[k] < self.min_probability]
        for k in rare:
            self.reinitialise(k, rng)
        return sorted(close | set(rare))

    def select(self, rng: np.random.Generator) -> int:
        self.probabilities = self.probabilities / self.probabilities.sum()
        return int(rng.choice(self.n, p=self.probabilities))

    def mark_worst(self, k: int, episode_length: int) -> None:
        """``p ← (1 - 1/L) p + (1/L) e_k``: a decaying average of which candidate is worst."""
        coeff = 1.0 / max(1, episode_length)
        self.probabilities *= 1.0 - coeff
        self.probabilities[k] += coeff

    def state(self) -> dict[str, object]:
        return {
            "logits": torch.stack([p.detach() for p in self.logits]),
            "optimizers": [opt.state_dict() for opt in self.optimizers],
            "probabilities": torch.as_tensor(self.probabilities),
        }

    def restore(self, state: dict[str, object]) -> None:
        with torch.no_grad():
            for k, p in enumerate(self.logits):
                p.copy_(state["logits"][k])
        for k, opt_state in enumerate(state["optimizers"]):
            self.optimizers[k] = torch.optim.Adam([self.logits[k]], lr=self.learning_rate)
            self.optimizers[k].load_state_dict(opt_state)
        self.probabilities = state["probabilities"].numpy().astype(np.float64).copy()


def make_env(task: str, uncertainty: str, config: Config) -> Any:
    """The task's env of the set's family; the learner sets ω at every reset."""
    return task_env(task, uncertainty)[0]


class Learner(_Learner):
    """TD3 with ω-conditioned critics, the candidates ω̂ and the episode's ω."""

    def __init__(
        self, env: Any, config: Config, run: TrainConfig, rng: np.random.Generator
    ) -> None:
        self.box = box = task_env(run.task, run.uncertainty)[1]
        obs_dim = env.observation_space.shape[0]
        self.low, self.high = env.action_space.low, env.action_space.high
        act_dim, dim = len(self.low), box.dim
        half = (box.high - box.low) / 2
        self.config, self.max_episode_steps = config, run.max_episode_steps
        device = run.device
        self.agent = TD3(
            obs_dim,
            act_dim,
            self.low,
            self.high,
            config,
            seed=run.seed,
            device=device,
            cond_dim=dim,
        )
        self.actor = self.agent.actor
        self.buffer = ReplayBuffer(
            min(config.buffer_size, run.steps),
            transition_fields(obs_dim, (act_dim,), omega=(dim,)),
            device=device,
            seed=run.seed + 2,
        )
        self.candidates = Candidates(
            box.low,
            box.high,
            rng,
            config.hatomega_number,
            config.hatomega_learning_rate,
            config.hatomega_parameter_distance,
            config.minimum_probability,
        ).to(device)
        self.omega_std = config.omega_std_rate * half

        def tensor(x: np.ndarray) -> torch.Tensor:
            return torch.as_tensor(np.array(x), dtype=torch.float32, device=device)

        self.omega_low, self.omega_high = tensor(box.low), tensor(box.high)
        self.noise_scale = tensor(config.policy_noise_rate * half)
        self.noise_clip = tensor(config.noise_clip_omega_rate * half)
        self.last_length = run.max_episode_steps
        self.omega = np.zeros(dim)

    def critic_omega(self, w: torch.Tensor) -> torch.Tensor:
        """The critics' view of ω: raw (the authors) or rescaled to [-1, 1] (opt-in)."""
        if not self.config.normalize_omega:
            return w
        return (w - self.omega_low) / (self.omega_high - self.omega_low) * 2.0 - 1.0

    def episode_options(self, step: int, rng: np.random.Generator) -> dict[str, Any]:
        """ω for the next episode: uniform at first, then around a selected candidate."""
        box = self.box
        if step < self.config.learning_starts:
            self.omega = rng.uniform(box.low, box.high)
        else:
            self.candidates.restart(rng)
            k = self.candidates.select(rng)
            centre = self.candidates.value(k).detach().cpu().numpy()
            self.omega = np.clip(centre + rng.normal(0, self.omega_std), box.low, box.high)
        return dict(zip(box.names, self.omega.tolist()))

    act = td3.Learner.act  # acts as TD3: uniform during the warm-up, then π(s) + noise

    def store(self, obs, action, reward, next_obs, terminated, info) -> None:  # noqa: ANN001
        self.buffer.add(
            obs=obs,
            action=action,
            reward=reward,
            next_obs=next_obs,
            terminated=float(terminated),
            omega=self.omega,
        )

    def update(self, step: int, update_actor: bool) -> dict[str, torch.Tensor]:
        agent, candidates, cw = self.agent, self.candidates, self.critic_omega
        batch = self.buffer.sample(self.config.batch_size)
        # critic: TD3's target with smoothing noise on the next action *and* on ω
        eps = torch.randn(batch["omega"].shape, generator=agent.noise, device=agent.device)
        eps = torch.maximum(
            torch.minimum(eps * self.noise_scale, self.noise_clip), -self.noise_clip
        )
        next_w = torch.maximum(torch.minimum(batch["omega"] + eps, self.omega_high), self.omega_low)
        y = agent.td_target(
            batch["reward"], batch["next_obs"], batch["terminated"], next_cond=cw(next_w)
        )
        losses = {
            "critic_loss": agent.update_critic(
                batch["obs"], batch["action"], y, cond=cw(batch["omega"])
            )
        }
        if not update_actor:
            return losses
        # the worst candidate: the lowest mean Q1(s, π(s), ω̂ₖ)
        s = batch["obs"]
        with torch.no_grad():
            a = agent.actor(s)
            w = candidates.values().to(agent.device)
            n, b = len(w), len(s)
            x = torch.cat((s.repeat(n, 1), a.repeat(n, 1), cw(w).repeat_interleave(b, 0)), dim=1)
            q = agent.critic.q1(x).view(n, b).mean(1)
        k = int(n - 1 - torch.argmin(q.flip(0)))  # ties: the last, as the authors
        worst = w[k].expand(b, -1)
        # ω̂ₖ descends Q1(s, π(s), ω̂ₖ)
        omega_loss = agent.critic.q1(
            torch.cat((s, a, cw(candidates.value(k)).expand(b, -1)), dim=1)
        ).mean()
        candidates.optimizers[k].zero_grad(set_to_none=True)
        omega_loss.backward(inputs=[candidates.logits[k]])
        candidates.optimizers[k].step()
        losses["actor_loss"] = agent.update_actor(s, cond=cw(worst))
        agent.update_targets()
        candidates.mark_worst(k, self.last_length)
        losses["omega_loss"] = omega_loss.detach()
        return losses

    def episode_end(self, episode_return: float, length: int) -> dict[str, float]:
        self.last_length = length
        values = self.candidates.values().cpu().numpy()
        extra = {f"m2td3/probability_{k}": p for k, p in enumerate(self.candidates.probabilities)}
        extra.update(
            {
                f"m2td3/hatomega_{k}_{name}": values[k, i]
                for k in range(len(values))
                for i, name in enumerate(self.box.names)
            }
        )
        return extra

    def summary(self) -> dict[str, Any]:
        return {
            "hatomega": self.candidates.values().tolist(),
            "probabilities": self.candidates.probabilities.tolist(),
        }

    def state_dict(self) -> dict[str, Any]:
        return {
            "agent": self.agent.state_dict(),
            "buffer": self.buffer.state_dict(),
            "candidates": self.candidates.state(),
            "last_length": self.last_length,
        }

    def load_state_dict(self, state: dict[str, Any]) -> None:
        self.agent.load_state_dict(state["agent"])
        self.buffer.load_state_dict(state["buffer"])
        self.candidates.restore(state["candidates"])
        self.last_length = int(state["last_length"])
