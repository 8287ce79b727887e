"""M2TD3 (Tanabe et al. 2022, "Max-Min Off-Policy Actor-Critic Method Focusing on Worst-Case
Robustness to Model Misspecification"), on the TD3 core, following the authors' code
(github.com/akimotolab/M2TD3) and the paper's M2TD3 table.

- Critics ``Q(s, a, ω)`` take the uncertainty parameters ω (raw values, as the authors do).
- ``N = 5`` candidate worst-case parameters ω̂ₖ, each ``low + sigmoid(θₖ) (high - low)`` so they
  stay inside the box, initialised uniformly, each with its own Adam (lr 3e-4).
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
``min_omega_std_rate`` but never calls it). One deliberate difference: the authors store
time-limit truncations as terminal; here truncated transitions bootstrap, as in our TD3.

Opt-in (``normalize_omega`` / ``--normalize-omega``): the critics see ω rescaled to [-1, 1]. The
authors feed raw values; on InvertedPendulum's pole mass (1-31) raw ω swamps the first layer and
M2TD3 barely learns in 20 k steps (average 51 over the 1D mesh, seed 1), rescaled it learns as
fast as DR (average 879). The same function class — only the optimisation's conditioning changes.
"""

from __future__ import annotations

from itertools import combinations
from pathlib import Path

import numpy as np
import torch

from rrls.agents.common import Run, TrainConfig, make_env, metadata, rng_state, set_rng_state
from rrls.agents.core import TD3
from rrls.agents.replay import ReplayBuffer, transition_fields


class Candidates(torch.nn.Module):
    """The N candidate worst-case parameters ω̂, always inside ``[low, high]``."""

    N = 5
    LEARNING_RATE = 3e-4
    DISTANCE = 0.1  # re-initialise a candidate this close (L1) to another
    MIN_PROBABILITY = 0.05

    def __init__(self, low: np.ndarray, high: np.ndarray, rng: np.random.Generator) -> None:
        super().__init__()
        self.register_buffer("low", torch.tensor(np.array(low), dtype=torch.float32))
        self.register_buffer("high", torch.tensor(np.array(high), dtype=torch.float32))
        self.logits = torch.nn.ParameterList(
            torch.nn.Parameter(torch.zeros(len(low))) for _ in range(self.N)
        )
        self.optimizers = [torch.optim.Adam([p], lr=self.LEARNING_RATE) for p in self.logits]
        self.probabilities = np.full(self.N, 1.0 / self.N)
        for k in range(self.N):
            self.reinitialise(k, rng, probability=False)

    def value(self, k: int) -> torch.Tensor:
        return self.low + torch.sigmoid(self.logits[k]) * (self.high - self.low)

    def values(self) -> torch.Tensor:
        """All candidates as an ``(N, dim)`` tensor (no gradient)."""
        with torch.no_grad():
            return torch.stack([self.value(k) for k in range(self.N)])

    def reinitialise(self, k: int, rng: np.random.Generator, probability: bool = True) -> None:
        """A fresh uniform point and a fresh Adam; its probability = the mean of the others."""
        low, high = self.low.cpu().numpy(), self.high.cpu().numpy()
        y = (rng.uniform(low, high) - low) / np.maximum(high - low, 1e-5)
        y = np.clip(y, 1e-5, 1 - 1e-5)
        with torch.no_grad():
            self.logits[k].copy_(torch.as_tensor(np.log(y / (1 - y)), dtype=torch.float32))
        self.optimizers[k] = torch.optim.Adam([self.logits[k]], lr=self.LEARNING_RATE)
        if probability:
            self.probabilities[k] = 0.0
            self.probabilities[k] = self.probabilities.sum() / (self.N - 1)

    def restart(self, rng: np.random.Generator) -> list[int]:
        """Re-initialise candidates that collapsed onto another or are rarely the worst."""
        values = self.values().cpu().numpy()
        close = {
            i
            for i, j in combinations(range(self.N), 2)
            if np.abs(values[i] - values[j]).sum() <= self.DISTANCE
        }
        for k in sorted(close):
            self.reinitialise(k, rng)
        rare = [k for k in range(self.N) if self.probabilities[k] < self.MIN_PROBABILITY]
        for k in rare:
            self.reinitialise(k, rng)
        return sorted(close | set(rare))

    def select(self, rng: np.random.Generator) -> int:
        self.probabilities = self.probabilities / self.probabilities.sum()
        return int(rng.choice(self.N, p=self.probabilities))

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
            self.optimizers[k] = torch.optim.Adam([self.logits[k]], lr=self.LEARNING_RATE)
            self.optimizers[k].load_state_dict(opt_state)
        self.probabilities = state["probabilities"].numpy().astype(np.float64).copy()


def train(config: TrainConfig, resume: bool = False) -> Path:
    """Train M2TD3 over ``config.uncertainty``; returns the run directory."""
    from rrls.envs import get_uncertainty_set

    box = get_uncertainty_set(config.task, config.uncertainty)
    env = make_env(config.task, "force" if config.uncertainty == "rarl" else "robust")
    run = Run(config, resume)
    obs_dim = env.observation_space.shape[0]
    low, high = env.action_space.low, env.action_space.high
    act_dim, dim = len(low), box.dim
    half = (box.high - box.low) / 2
    omega_std = 1.0 * half  # omega_std_rate
    omega_noise, omega_clip = 0.2 * half, 0.5 * half  # policy_noise_rate, noise_clip_omega_rate
    cfg = config.td3_config(batch_size=100)
    agent = TD3(
        obs_dim, act_dim, low, high, cfg, seed=config.seed, device=config.device, cond_dim=dim
    )
    buffer = ReplayBuffer(
        min(cfg.buffer_size, config.steps),
        transition_fields(obs_dim, (act_dim,), omega=(dim,)),
        device=config.device,
        seed=config.seed + 2,
    )
    rng = np.random.default_rng(config.seed)
    candidates = Candidates(box.low, box.high, rng).to(config.device)
    omega_low = torch.tensor(np.array(box.low), dtype=torch.float32, device=config.device)
    omega_high = torch.tensor(np.array(box.high), dtype=torch.float32, device=config.device)
    noise_scale = torch.as_tensor(omega_noise, dtype=torch.float32, device=config.device)
    noise_clip = torch.as_tensor(omega_clip, dtype=torch.float32, device=config.device)
    meta = metadata(config, obs_dim, act_dim)

    def critic_omega(w: torch.Tensor) -> torch.Tensor:
        """The critics' view of ω: raw (the authors) or rescaled to [-1, 1] (opt-in)."""
        if not config.normalize_omega:
            return w
        return (w - omega_low) / (omega_high - omega_low) * 2.0 - 1.0

    last_length = config.max_episode_steps

    def next_omega() -> np.ndarray:
        """ω for the next episode: uniform at first, then around a selected candidate."""
        if run.step < cfg.learning_starts:
            return rng.uniform(box.low, box.high)
        candidates.restart(rng)
        k = candidates.select(rng)
        return np.clip(
            candidates.value(k).detach().cpu().numpy() + rng.normal(0, omega_std), box.low, box.high
        )

    state = run.load()
    if state is not None:
        agent.load_state_dict(state["agent"])
        buffer.load_state_dict(state["buffer"])
        candidates.restore(state["candidates"])
        set_rng_state(rng, state["rng"])
        set_rng_state(env.np_random, state["env_rng"])
        last_length = int(state["last_length"])
    omega = next_omega()
    params = dict(zip(box.names, omega.tolist()))
    obs, _ = env.reset(seed=config.seed if state is None else None, options=params)

    bar = run.progress()
    episode_return, episode_length = 0.0, 0
    try:
        while run.step < config.steps:
            if run.step < cfg.learning_starts:
                action = rng.uniform(low, high).astype(np.float32)
            else:
                action = agent.explore(obs, rng)
            next_obs, reward, terminated, _, _ = env.step(action)
            run.step += 1
            episode_return += reward
            episode_length += 1
            truncated = episode_length >= config.max_episode_steps
            buffer.add(
                obs=obs,
                action=action,
                reward=reward,
                next_obs=next_obs,
                terminated=float(terminated),
                omega=omega,
            )
            obs = next_obs

            if run.step > cfg.learning_starts:
                batch = buffer.sample(cfg.batch_size)
                # critic: TD3's target with smoothing noise on the next action *and* on ω
                eps = torch.randn(batch["omega"].shape, generator=agent.noise, device=agent.device)
                eps = torch.maximum(torch.minimum(eps * noise_scale, noise_clip), -noise_clip)
                next_w = torch.maximum(torch.minimum(batch["omega"] + eps, omega_high), omega_low)
                y = agent.td_target(
                    batch["reward"],
                    batch["next_obs"],
                    batch["terminated"],
                    next_cond=critic_omega(next_w),
                )
                critic_loss = agent.update_critic(
                    batch["obs"], batch["action"], y, cond=critic_omega(batch["omega"])
                )
                if run.step % cfg.policy_frequency == 0:
                    # the worst candidate: the lowest mean Q1(s, π(s), ω̂ₖ)
                    s = batch["obs"]
                    with torch.no_grad():
                        a = agent.actor(s)
                        w = candidates.values().to(agent.device)
                        n, b = len(w), len(s)
                        x = torch.cat(
                            (
                                s.repeat(n, 1),
                                a.repeat(n, 1),
                                critic_omega(w).repeat_interleave(b, 0),
                            ),
                            dim=1,
                        )
                        q = agent.critic.q1(x).view(n, b).mean(1)
                    k = int(n - 1 - torch.argmin(q.flip(0)))  # ties: the last, as the authors
                    worst = w[k].expand(b, -1)
                    # ω̂ₖ descends Q1(s, π(s), ω̂ₖ)
                    omega_loss = agent.critic.q1(
                        torch.cat((s, a, critic_omega(candidates.value(k)).expand(b, -1)), dim=1)
                    ).mean()
                    candidates.optimizers[k].zero_grad(set_to_none=True)
                    omega_loss.backward(inputs=[candidates.logits[k]])
                    candidates.optimizers[k].step()
                    actor_loss = agent.update_actor(s, cond=critic_omega(worst))
                    agent.update_targets()
                    candidates.mark_worst(k, last_length)
                    if run.step % 1000 == 0:
                        run.log(
                            {
                                "losses/critic_loss": critic_loss.item(),
                                "losses/actor_loss": actor_loss.item(),
                                "losses/omega_loss": omega_loss.item(),
                            }
                        )
            if run.eval_due():
                run.evaluate(agent.actor, meta)

            if terminated or truncated:
                values = candidates.values().cpu().numpy()
                extra = {
                    f"m2td3/probability_{k}": p for k, p in enumerate(candidates.probabilities)
                }
                extra.update(
                    {
                        f"m2td3/hatomega_{k}_{name}": values[k, i]
                        for k in range(len(values))
                        for i, name in enumerate(box.names)
                    }
                )
                run.episode_end(episode_return, episode_length, **extra)
                last_length = episode_length
                episode_return, episode_length = 0.0, 0
                if run.checkpoint_due():
                    run.save(
                        {
                            "agent": agent.state_dict(),
                            "buffer": buffer.state_dict(),
                            "candidates": candidates.state(),
                            "rng": rng_state(rng),
                            "env_rng": rng_state(env.np_random),
                            "last_length": last_length,
                        }
                    )
                omega = next_omega()
                obs, _ = env.reset(options=dict(zip(box.names, omega.tolist())))
            bar.update(1)
    finally:
        run.close()
    return run.finish(
        agent.actor,
        meta,
        {
            "steps": run.step,
            "episodes": run.episodes,
            "hatomega": candidates.values().tolist(),
            "probabilities": candidates.probabilities.tolist(),
        },
    )
