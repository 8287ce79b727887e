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
from rrls.agents.core import TD3, TD3Config, Update, hp
from rrls.agents.networks import per_run
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


class Candidates:
    """Each run's ``N`` candidate worst-case parameters ω̂, always inside ``[low, high]``.

    Stacked for the group: logits ``(K, N, dim)``, each candidate with its own Adam state (as the
    authors' one optimiser per ω̂; restarted with it), selection probabilities ``(K, N)``.
    """

    def __init__(
        self,
        low: np.ndarray,
        high: np.ndarray,
        rngs: list[np.random.Generator],
        config: Config,
        device: torch.device,
    ) -> None:
        self.n, self.learning_rate = config.hatomega_number, config.hatomega_learning_rate
        self.distance = config.hatomega_parameter_distance
        self.min_probability = config.minimum_probability
        self.low_np, self.high_np = np.asarray(low, np.float64), np.asarray(high, np.float64)
        self.low = torch.tensor(self.low_np, dtype=torch.float32, device=device)
        self.high = torch.tensor(self.high_np, dtype=torch.float32, device=device)
        shape = (len(rngs), self.n, len(low))
        self.logits = torch.zeros(shape, device=device)
        self.exp_avg = torch.zeros(shape, device=device)
        self.exp_avg_sq = torch.zeros(shape, device=device)
        # β^t as running products (exact multiplications; a tensor ``pow`` is transcendental)
        self.beta_powers = torch.ones((*shape[:2], 2), device=device)
        self._betas = torch.tensor([0.9, 0.999], device=device)
        self.probabilities = torch.full(shape[:2], 1.0 / self.n, dtype=torch.float64, device=device)
        for k, rng in enumerate(rngs):
            for j in range(self.n):
                self.reinitialise(k, j, rng, probability=False)

    def values(self) -> torch.Tensor:
        """All candidates, ``(K, N, dim)``."""
        return self.low + per_run(torch.sigmoid, self.logits) * (self.high - self.low)

    def reinitialise(
        self, k: int, j: int, rng: np.random.Generator, probability: bool = True
    ) -> None:
        """A fresh uniform point and a fresh Adam; its probability = the mean of the others."""
        low, high = self.low_np, self.high_np
        y = (rng.uniform(low, high) - low) / np.maximum(high - low, 1e-5)
        y = np.clip(y, 1e-5, 1 - 1e-5)
        self.logits[k, j] = torch.as_tensor(np.log(y / (1 - y)), dtype=torch.float32)
        self.exp_avg[k, j] = 0.0
        self.exp_avg_sq[k, j] = 0.0
        self.beta_powers[k, j] = 1.0
        if probability:
            p = self.probabilities[k]
            p[j] = 0.0
            p[j] = p.sum() / (self.n - 1)

    def restart(self, k: int, rng: np.random.Generator) -> list[int]:
        """Re-initialise run ``k``'s candidates that collapsed onto another or are rarely the
        worst."""
        values = self.values()[k].cpu().numpy()
        close = {
            i
            for i, j in combinations(range(self.n), 2)
            if np.abs(values[i] - values[j]).sum() <= self.distance
        }
        for j in sorted(close):
            self.reinitialise(k, j, rng)
        probabilities = self.probabilities[k].cpu().numpy()
        rare = [j for j in range(self.n) if probabilities[j] < self.min_probability]
        for j in rare:
            self.reinitialise(k, j, rng)
        return sorted(close | set(rare))

    def select(self, k: int, rng: np.random.Generator) -> int:
        p = self.probabilities[k]
        p /= p.sum()
        return int(rng.choice(self.n, p=p.cpu().numpy()))

    @torch.no_grad()
    def step(self, chosen: torch.Tensor, grad_logits: torch.Tensor) -> None:
        """One Adam step (``torch.optim.Adam``'s arithmetic) of each run's chosen candidate."""
        beta1, beta2, eps = 0.9, 0.999, 1e-8
        index = chosen.view(-1, 1, 1).expand(-1, 1, self.logits.shape[2])
        index2 = chosen.view(-1, 1, 1).expand(-1, 1, 2)
        powers = self.beta_powers.gather(1, index2).squeeze(1)  # (K, 2)
        powers.mul_(self._betas)
        m = self.exp_avg.gather(1, index).squeeze(1).lerp_(grad_logits, 1 - beta1)
        v = self.exp_avg_sq.gather(1, index).squeeze(1).mul_(beta2)
        v.addcmul_(grad_logits, grad_logits, value=1 - beta2)
        bias1, bias2 = 1 - powers[:, :1], 1 - powers[:, 1:]
        denom = (v.sqrt() / bias2.sqrt()).add_(eps)
        logits = self.logits.gather(1, index).squeeze(1)
        logits.addcdiv_(m, denom * bias1 / self.learning_rate, value=-1.0)
        self.beta_powers.scatter_(1, index2, powers.unsqueeze(1))
        self.exp_avg.scatter_(1, index, m.unsqueeze(1))
        self.exp_avg_sq.scatter_(1, index, v.unsqueeze(1))
        self.logits.scatter_(1, index, logits.unsqueeze(1))

    def mark_worst(self, chosen: torch.Tensor, coeff: torch.Tensor) -> None:
        """``p ← (1 - 1/L) p + (1/L) e_k`` per run: a decaying average of which is worst."""
        self.probabilities.mul_(1.0 - coeff.unsqueeze(1))
        self.probabilities.scatter_add_(1, chosen.view(-1, 1), coeff.unsqueeze(1))

    def stacked(self) -> dict[str, torch.Tensor]:
        return {
            "hatomega.logits": self.logits,
            "hatomega.exp_avg": self.exp_avg,
            "hatomega.exp_avg_sq": self.exp_avg_sq,
            "hatomega.beta_powers": self.beta_powers,
            "hatomega.probabilities": self.probabilities,
        }


def make_env(task: str, uncertainty: str, config: Config) -> Any:
    """The task's env of the set's family; the learner sets ω at every reset."""
    return task_env(task, uncertainty)[0]


class Learner(td3.Learner):
    """TD3 with ω-conditioned critics, the candidates ω̂ and each run's episode ω (acting,
    checkpointed generators and buffers as TD3's learner)."""

    def __init__(
        self,
        env: Any,
        config: Config,
        runs: list[TrainConfig],
        rngs: list[np.random.Generator],
    ) -> None:
        self.box = box = task_env(runs[0].task, runs[0].uncertainty)[1]
        obs_dim = env.observation_space.shape[0]
        self.low, self.high = env.action_space.low, env.action_space.high
        act_dim, dim = len(self.low), box.dim
        half = (box.high - box.low) / 2
        self.config = config
        seeds, device = [r.seed for r in runs], runs[0].device
        self.agent = TD3(obs_dim, act_dim, self.low, self.high, config, seeds, device, cond_dim=dim)
        self.actor = self.agent.actor
        self.buffer = ReplayBuffer(
            min(config.buffer_size, runs[0].steps),
            transition_fields(obs_dim, (act_dim,), omega=(dim,)),
            device,
            [s + 2 for s in seeds],
        )
        device = self.agent.device
        self.candidates = Candidates(box.low, box.high, rngs, config, device)
        self.omega_std = config.omega_std_rate * half

        def tensor(x: np.ndarray) -> torch.Tensor:
            return torch.as_tensor(np.array(x), dtype=torch.float32, device=device)

        self.omega_low, self.omega_high = tensor(box.low), tensor(box.high)
        self.noise_scale = tensor(config.policy_noise_rate * half)
        self.noise_clip = tensor(config.noise_clip_omega_rate * half)
        self.last_length = [runs[0].max_episode_steps] * len(runs)
        self.coeff = torch.full(
            (len(runs),),
            1.0 / max(1, runs[0].max_episode_steps),
            dtype=torch.float64,
            device=device,
        )
        self.omega = np.zeros((len(runs), dim))
        self._omega_columns = slice(obs_dim + act_dim, obs_dim + act_dim + dim)
        self._update = Update(self._compute, device, runs[0].cuda_graphs)

    def critic_omega(self, w: torch.Tensor) -> torch.Tensor:
        """The critics' view of ω: raw (the authors) or rescaled to [-1, 1] (opt-in)."""
        if not self.config.normalize_omega:
            return w
        return (w - self.omega_low) / (self.omega_high - self.omega_low) * 2.0 - 1.0

    def episode_options(self, k: int, step: int, rng: np.random.Generator) -> dict[str, Any]:
        """Run ``k``'s ω for its next episode: uniform at first, then around a candidate."""
        box = self.box
        if step < self.config.learning_starts:
            self.omega[k] = rng.uniform(box.low, box.high)
        else:
            self.candidates.restart(k, rng)
            j = self.candidates.select(k, rng)
            centre = self.candidates.values()[k, j].cpu().numpy().astype(np.float64)
            self.omega[k] = np.clip(centre + rng.normal(0, self.omega_std), box.low, box.high)
        return dict(zip(box.names, self.omega[k].tolist()))

    def store(self, obs, actions, rewards, next_obs, terminated, infos) -> None:  # noqa: ANN001
        self.buffer.add(
            obs=obs,
            action=actions,
            reward=rewards,
            next_obs=next_obs,
            terminated=terminated,
            omega=self.omega,
        )

    def update(self, step: int, update_actor: bool) -> dict[str, torch.Tensor]:
        size, agent = self.config.batch_size, self.agent
        draws = {"idx": self.buffer.draw(size)}
        draws["eps_omega"] = agent.draw(size, self.box.dim)  # ω's smoothing noise, then a's
        draws["eps"] = agent.draw(size)
        return self._update(update_actor, draws)

    def _compute(self, update_actor: bool, x: dict[str, torch.Tensor]) -> dict:
        """The device work of an update (``core.Update`` may capture it in a CUDA graph)."""
        agent, candidates, cw = self.agent, self.candidates, self.critic_omega
        batch, eps_omega, eps = self.buffer.gather(x["idx"]), x["eps_omega"], x["eps"]
        # critic: TD3's target with smoothing noise on the next action *and* on ω
        noise = torch.maximum(
            torch.minimum(eps_omega * self.noise_scale, self.noise_clip), -self.noise_clip
        )
        next_w = torch.maximum(
            torch.minimum(batch["omega"] + noise, self.omega_high), self.omega_low
        )
        y = agent.td_target(
            batch["reward"], batch["next_obs"], batch["terminated"], eps, next_cond=cw(next_w)
        )
        losses = {
            "critic_loss": agent.update_critic(
                batch["obs"], batch["action"], y, cond=cw(batch["omega"])
            )
        }
        if not update_actor:
            return losses
        with torch.no_grad():
            # the worst candidate of each run: the lowest mean Q1(s, π(s), ω̂ₖ)
            s = batch["obs"]
            a = agent.actor.forward_saved(s)[0]
            w = candidates.values()
            k, n, b = w.shape[0], w.shape[1], s.shape[1]
            x = torch.cat(
                (s.repeat(1, n, 1), a.repeat(1, n, 1), cw(w).repeat_interleave(b, 1)), dim=2
            )
            q = agent.critic.forward_saved(x, n=1)[0].view(k, n, b).mean(2)
            chosen = n - 1 - torch.argmin(q.flip(1), dim=1)  # ties: the last, as the authors
            worst = w.gather(1, chosen.view(-1, 1, 1).expand(-1, 1, w.shape[2]))
            worst = worst.expand(-1, b, -1)
            # ω̂ₖ descends Q1(s, π(s), ω̂ₖ): dQ1/dω through the critic, then through cw and the
            # sigmoid to the logits
            q1, saved = agent.critic.forward_saved(torch.cat((s, a, cw(worst)), dim=2), n=1)
            grad_w = agent.critic.backward_saved(
                saved, torch.full_like(q1, 1.0 / b), input_columns=self._omega_columns
            ).sum(1)
            span = self.omega_high - self.omega_low
            if self.config.normalize_omega:
                grad_w = grad_w * (2.0 / span)
            sig = per_run(
                torch.sigmoid,
                candidates.logits.gather(
                    1, chosen.view(-1, 1, 1).expand(-1, 1, w.shape[2])
                ).squeeze(1),
            )
            candidates.step(chosen, grad_w * span * sig * (1.0 - sig))
        losses["actor_loss"] = agent.update_actor(s, cond=cw(worst))
        agent.update_targets()
        candidates.mark_worst(chosen, self.coeff)
        losses["omega_loss"] = q1.mean((1, 2))
        return losses

    def episode_end(self, k: int, episode_return: float, length: int) -> dict[str, float]:
        self.last_length[k] = length
        self.coeff[k] = 1.0 / max(1, length)
        values = self.candidates.values()[k].cpu().numpy()
        probabilities = self.candidates.probabilities[k].cpu().numpy()
        extra = {f"m2td3/probability_{j}": p for j, p in enumerate(probabilities)}
        extra.update(
            {
                f"m2td3/hatomega_{j}_{name}": values[j, i]
                for j in range(len(values))
                for i, name in enumerate(self.box.names)
            }
        )
        return extra

    def summary(self, k: int) -> dict[str, Any]:
        return {
            "hatomega": self.candidates.values()[k].tolist(),
            "probabilities": self.candidates.probabilities[k].tolist(),
        }

    def stacked(self) -> dict[str, torch.Tensor]:
        return {**super().stacked(), **self.candidates.stacked()}

    def extra_state(self, k: int) -> dict[str, Any]:
        return {"last_length": self.last_length[k], "omega": torch.as_tensor(self.omega[k])}

    def load_extra_state(self, k: int, state: dict[str, Any]) -> None:
        self.last_length[k] = int(state["last_length"])
        self.coeff[k] = 1.0 / max(1, self.last_length[k])
        self.omega[k] = state["omega"].numpy()
