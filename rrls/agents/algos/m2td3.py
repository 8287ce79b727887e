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
time-limit truncations as terminal, here truncated transitions bootstrap, as in our TD3. The
random warm-up is the authors' ``start_steps`` = 100 k steps (``src/main_m2td3.py:16`` of the
RRLS authors' port, ``SuReLI/TCRMDP``; akimotolab/M2TD3's configs), four times TD3's 25 k: the
RRLS table gives none for M2TD3, so its authors' code decides.

Opt-in (``normalize_omega`` / ``--normalize-omega``): the critics see ω rescaled to [-1, 1]. The
authors feed raw values; on InvertedPendulum's pole mass (1-31) raw ω swamps the first layer and
M2TD3 barely learns in 20 k steps (average 51 over the 1D mesh, seed 1), rescaled it learns as
fast as DR (average 879). The same function class — only the optimisation's conditioning changes.

Opt-in, two details of the authors' trainer every rrls baseline leaves off: ``clip_exploration=
False`` (the exploring action stored and sent unclipped, ``src/m2td3/algo.py:471-494``) and
``same_start`` (every episode reset with the run's one seed, ``src/m2td3/trainer.py:197``).
"""

from __future__ import annotations

from dataclasses import dataclass
from itertools import combinations
from typing import Any

import numpy as np
import torch
from torch import nn

from rrls.agents.algos.td3 import TD3, TD3Config
from rrls.agents.algos.td3 import Learner as TD3Learner
from rrls.agents.envs import task_env
from rrls.agents.graphs import Update, adam
from rrls.agents.hparams import hp
from rrls.agents.replay import ReplayBuffer, transition_fields
from rrls.agents.streams import NumpyGenerators, RunSeeds
from rrls.algorithms import warmup


@dataclass
class Config(TD3Config):
    """The paper's M2TD3 table (``hyperparameters_m2td3``) on top of TD3's."""

    batch_size: int = hp(100, "replay batch size (M2TD3's table: 100)")
    learning_starts: int = hp(
        warmup("m2td3"),
        "uniformly random steps before learning starts (the authors' start_steps = 1e5: "
        "SuReLI/TCRMDP src/main_m2td3.py:16, akimotolab/M2TD3's configs)",
    )
    hatomega_number: int = hp(
        5, "candidate worst-case parameters ω̂ (each scored every update)", most=10_000
    )
    hatomega_learning_rate: float = hp(3e-4, "Adam step size of the ω̂ (the table's own rate)")
    hatomega_parameter_distance: float = hp(0.1, "restart a ω̂ this close (L1) to another")
    minimum_probability: float = hp(0.05, "restart a ω̂ whose probability falls below this")
    omega_std_rate: float = hp(1.0, "ω exploration noise, times the set's half-range")
    policy_noise_rate: float = hp(0.2, "target smoothing noise on ω, times the half-range")
    noise_clip_omega_rate: float = hp(0.5, "clip of that noise, times the half-range")
    normalize_omega: bool = hp(
        False, "critics see ω rescaled to [-1, 1] (the authors feed raw values)"
    )
    clip_exploration: bool = hp(
        True,
        "exploring actions clipped to the action box before they are stored (the authors "
        "store and send them unclipped; MuJoCo clamps the control)",
    )
    same_start: bool = hp(
        False, "every episode reset with the run's first seed: one start state (the authors')"
    )

    def __post_init__(self) -> None:
        super().__post_init__()
        if self.hatomega_number < 2:
            raise ValueError(f"hatomega_number must be >= 2, got {self.hatomega_number}")
        lr = self.hatomega_learning_rate
        if not (np.isfinite(lr) and lr > 0):
            raise ValueError(f"hatomega_learning_rate must be a positive number, got {lr}")


class Candidates:
    """Each run's ``N`` candidate worst-case parameters ω̂ = low + sigmoid(logit) · (high - low),
    always inside the box, with selection probabilities ``(K, N)``.

    Every candidate is its own parameter with its own Adam state (the authors' one optimiser per
    ω̂, restarted with it): one ``torch.optim.Adam`` over the ``K·N`` logits, of which only the
    chosen ones get a gradient (the others are skipped, their step counts unchanged).
    """

    def __init__(self, low, high, rngs, config: Config, device: torch.device) -> None:
        self.n, self.group = config.hatomega_number, len(rngs.list)
        self.distance = config.hatomega_parameter_distance
        self.min_probability = config.minimum_probability
        self.low_np, self.high_np = np.asarray(low, np.float64), np.asarray(high, np.float64)
        self.low = torch.tensor(self.low_np, dtype=torch.float32, device=device)
        self.high = torch.tensor(self.high_np, dtype=torch.float32, device=device)
        dim = len(self.low_np)
        self.logits = [
            nn.Parameter(torch.zeros(dim, device=device)) for _ in range(self.group * self.n)
        ]
        self.opt = torch.optim.Adam(self.logits, lr=config.hatomega_learning_rate)
        shape = (self.group, self.n)
        self.probabilities = torch.full(shape, 1.0 / self.n, dtype=torch.float64, device=device)
        for k in range(self.group):
            for j in range(self.n):
                self.reinitialise(k, j, rngs[k], probability=False)

    def values(self) -> torch.Tensor:
        """All candidates, ``(K, N, dim)`` (differentiable in the logits)."""
        logits = torch.stack(self.logits).view(self.group, self.n, -1)
        return self.low + torch.sigmoid(logits) * (self.high - self.low)

    @torch.no_grad()
    def reinitialise(self, k: int, j: int, rng, probability: bool = True) -> None:
        """A fresh uniform point and a fresh Adam; its probability = the mean of the others."""
        low, high = self.low_np, self.high_np
        y = np.clip((rng.uniform(low, high) - low) / np.maximum(high - low, 1e-5), 1e-5, 1 - 1e-5)
        logit = self.logits[k * self.n + j]
        logit.copy_(torch.as_tensor(np.log(y / (1 - y)), dtype=torch.float32))
        self.opt.state.pop(logit, None)
        if probability:
            p = self.probabilities[k]
            p[j] = 0.0
            p[j] = p.sum() / (self.n - 1)

    def restart(self, k: int, rng) -> list[int]:
        """Re-initialise run ``k``'s candidates that collapsed onto another or are rarely the
        worst."""
        with torch.no_grad():
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

    def select(self, k: int, rng) -> int:
        p = self.probabilities[k]
        p /= p.sum()
        return int(rng.choice(self.n, p=p.cpu().numpy()))

    def step(self, loss: torch.Tensor, chosen: torch.Tensor) -> None:
        """One Adam step of each run's chosen candidate on its ``(K,)`` loss."""
        self.opt.zero_grad(set_to_none=True)
        mine = [self.logits[k * self.n + j] for k, j in enumerate(chosen.tolist())]
        loss.sum().backward(inputs=mine)  # the others keep no gradient: Adam skips them
        self.opt.step()

    @torch.no_grad()
    def mark_worst(self, chosen: torch.Tensor, coeff: torch.Tensor) -> None:
        """``p ← (1 - 1/L) p + (1/L) e_k`` per run: a decaying average of which is worst."""
        self.probabilities.mul_(1.0 - coeff.unsqueeze(1))
        self.probabilities.scatter_add_(1, chosen.view(-1, 1), coeff.unsqueeze(1))

    # -- on the device (the twin's resident loop): the same rules on every run at once, masked by
    # the runs whose episode begins, with no host read (``Learner.begin_episodes``)
    @torch.no_grad()
    def to_storage(self) -> None:
        """The logits and their Adam states as rows of four ``(K·N, ...)`` tensors (each
        candidate still its own parameter, a view of its row), so a masked write resets many."""
        self.rows = torch.stack([p.detach() for p in self.logits]).clone()
        moments = [torch.zeros_like(self.rows) for _ in range(2)]
        steps = torch.zeros(len(self.logits), dtype=torch.float32, device=self.rows.device)
        for i, p in enumerate(self.logits):
            state = self.opt.state.get(p, {})
            if state:
                moments[0][i], moments[1][i] = state["exp_avg"], state["exp_avg_sq"]
                steps[i] = state["step"]
        self.logits = [nn.Parameter(self.rows[i]) for i in range(len(self.logits))]
        # capturable on a GPU, fused on a CPU: no step count read back (``graphs.adam``)
        self.opt = adam(self.logits, self.opt.defaults["lr"], self.rows.device)
        self.state_rows = [*moments, steps]
        # made once, read at every step: each run's first row, and the box's span
        self.first_rows = torch.arange(self.group, device=self.rows.device) * self.n
        self.span = (self.high - self.low).double()
        for i, p in enumerate(self.logits):
            self.opt.state[p] = {"exp_avg": moments[0][i], "exp_avg_sq": moments[1][i]}
            self.opt.state[p]["step"] = steps[i]

    @torch.no_grad()
    def _reinitialise_masked(self, j: int, mask: torch.Tensor, u: torch.Tensor) -> None:
        """``reinitialise(k, j)`` for every run ``k`` of ``mask``, ``u`` its uniform draw."""
        y = (u.double() * self.span / self.span.clamp(min=1e-5)).clamp(1e-5, 1 - 1e-5)
        rows = self.first_rows + j
        fresh = torch.log(y / (1 - y)).float()
        self.rows[rows] = torch.where(mask[:, None], fresh, self.rows[rows])
        for state in self.state_rows:
            state[rows] = torch.where(_per_row(mask, state), 0, state[rows])
        p = self.probabilities
        p[:, j] = torch.where(mask, 0.0, p[:, j])
        p[:, j] = torch.where(mask, p.sum(1) / (self.n - 1), p[:, j])

    @torch.no_grad()
    def restart_masked(self, mask: torch.Tensor, close_u: torch.Tensor, rare_u: torch.Tensor):
        """``restart`` for the runs of ``mask`` (``(K,)``): the collapsed candidates first, in
        index order, then the rare ones, each with its own uniform draw (``(K, N, dim)``)."""
        v = self.values()
        near = (v[:, :, None] - v[:, None]).abs().sum(-1) <= self.distance
        later = torch.ones(self.n, self.n, dtype=torch.bool, device=v.device).triu(1)
        close = (near & later).any(2) & mask[:, None]
        for j in range(self.n):
            self._reinitialise_masked(j, close[:, j], close_u[:, j])
        rare = (self.probabilities < self.min_probability) & mask[:, None]
        for j in range(self.n):
            self._reinitialise_masked(j, rare[:, j], rare_u[:, j])

    @torch.no_grad()
    def select_drawn(self, mask: torch.Tensor, u: torch.Tensor) -> torch.Tensor:
        """``select`` for every run (``u``: its uniform draw, ``(K,)``), numpy's
        ``choice(p=p)`` arithmetic; only the runs of ``mask`` have their ``p`` renormalised."""
        p = self.probabilities
        p.copy_(torch.where(mask[:, None], p / p.sum(1, keepdim=True), p))
        cdf = p.cumsum(1)
        cdf = cdf / cdf[:, -1:]
        chosen = torch.searchsorted(cdf, u.double()[:, None], right=True)[:, 0]
        return chosen.clamp(max=self.n - 1)

    def step_masked(self, loss: torch.Tensor, chosen: torch.Tensor) -> None:
        """``step`` without reading ``chosen`` back: every candidate takes the Adam step, and
        all but the chosen ones are put back as they were (the authors' skipped optimisers)."""
        self.opt.zero_grad(set_to_none=True)
        loss.sum().backward(inputs=self.logits)
        with torch.no_grad():
            before = [self.rows.clone(), *(s.clone() for s in self.state_rows)]
            self.opt.step()
            mine = torch.zeros(self.group * self.n, dtype=torch.bool, device=self.rows.device)
            mine[self.first_rows + chosen] = True
            for now, old in zip([self.rows, *self.state_rows], before):
                now.copy_(torch.where(_per_row(mine, now), now, old))

    def state_dict(self) -> dict[str, torch.Tensor]:
        """Runs first: logits, Adam moments and step counts ``(K, N, ...)``, probabilities."""
        shape = (self.group, self.n)
        moments = {"exp_avg": [], "exp_avg_sq": [], "step": []}
        for p in self.logits:
            state = self.opt.state.get(p, {})
            moments["exp_avg"].append(state.get("exp_avg", torch.zeros_like(p)))
            moments["exp_avg_sq"].append(state.get("exp_avg_sq", torch.zeros_like(p)))
            moments["step"].append(torch.as_tensor(state.get("step", 0.0), dtype=torch.float32))
        out = {k: torch.stack(v).view(*shape, -1).detach().clone() for k, v in moments.items()}
        out["logits"] = torch.stack(self.logits).view(*shape, -1).detach().clone()
        out["probabilities"] = self.probabilities.clone()
        return out

    @torch.no_grad()
    def load_state_dict(self, state: dict[str, torch.Tensor]) -> None:
        logits = state["logits"].flatten(0, 1)
        exp_avg, exp_avg_sq = state["exp_avg"].flatten(0, 1), state["exp_avg_sq"].flatten(0, 1)
        for i, p in enumerate(self.logits):
            p.copy_(logits[i])
            step = float(state["step"].flatten(0, 1)[i, 0])
            self.opt.state.pop(p, None)
            if step > 0:
                self.opt.state[p] = {
                    "step": torch.tensor(step),
                    "exp_avg": exp_avg[i].clone().to(p.device),
                    "exp_avg_sq": exp_avg_sq[i].clone().to(p.device),
                }
        self.probabilities.copy_(state["probabilities"])


def _per_row(mask: torch.Tensor, like: torch.Tensor) -> torch.Tensor:
    """A ``(rows,)`` mask shaped to broadcast over ``like``'s rows."""
    return mask.view(-1, *[1] * (like.dim() - 1))


def make_env(task: str, uncertainty: Any, config: Config, paper: bool = False) -> Any:
    """The task's env of the set's family; the learner sets ω at every reset (``uncertainty_box``
    tells it the set)."""
    env, box = task_env(task, uncertainty, paper)
    env.uncertainty_box = box
    return env


class Learner(TD3Learner):
    """TD3 with ω-conditioned critics, the candidates ω̂ and each run's episode ω (acting and
    exploration as TD3's learner)."""

    def __init__(self, env: Any, config: Config, seeds: list[RunSeeds], device: Any) -> None:
        try:  # through any wrapper a user (or a benchmark's clock) put around make_env's env
            box = env.get_wrapper_attr("uncertainty_box")
        except AttributeError:
            box = None
        self.box = box
        if box is None:
            raise ValueError("M2TD3 needs an uncertainty set (--uncertainty 1d, 2d or 3d)")
        obs_dim = env.observation_space.shape[0]
        self.low, self.high = env.action_space.low, env.action_space.high
        self.config, dim, device = config, box.dim, torch.device(device)
        self.agent = TD3(obs_dim, self.low, self.high, config, seeds, device, cond_dim=dim)
        self.rngs = NumpyGenerators(seeds, "explore")
        self.sigma = (self.high - self.low) / 2 * config.exploration_noise
        self.buffer = ReplayBuffer(
            config.buffer_size,
            transition_fields(obs_dim, (len(self.low),), omega=(dim,)),
            device,
            seeds,
        )
        self.draws = NumpyGenerators(seeds, "algo")  # episode ω, candidate restarts
        self.candidates = Candidates(box.low, box.high, self.draws, config, device)
        half = (box.high - box.low) / 2
        self.omega_std = config.omega_std_rate * half

        def tensor(x: np.ndarray) -> torch.Tensor:
            return torch.as_tensor(np.array(x), dtype=torch.float32, device=device)

        self.omega_low, self.omega_high = tensor(box.low), tensor(box.high)
        self.noise_scale = tensor(config.policy_noise_rate * half)
        self.noise_clip = tensor(config.noise_clip_omega_rate * half)
        self.coeff = torch.full((len(seeds),), 1e-3, dtype=torch.float64, device=device)
        self.omega = np.zeros((len(seeds), dim))
        self.same_start = config.same_start
        self.run_seeds, self.on_device = seeds, False  # on_device: the twin's resident loop
        self.episode_ahead: dict[str, NumpyGenerators] | None = None  # made on first use
        self._update = Update(self._compute, device)

    def act(self, obs: np.ndarray) -> list[Any]:
        """TD3's ``π(s) + N(0, σ · scale)``; unclipped with ``clip_exploration=False``, as the
        authors' ``src/m2td3/algo.py:471-494`` (the same draws either way)."""
        if self.config.clip_exploration:
            return super().act(obs)
        return list(self.explore(obs).astype(np.float32))

    def critic_omega(self, w: torch.Tensor) -> torch.Tensor:
        """The critics' view of ω: raw (the authors) or rescaled to [-1, 1] (opt-in)."""
        if not self.config.normalize_omega:
            return w
        return (w - self.omega_low) / (self.omega_high - self.omega_low) * 2.0 - 1.0

    def episode_options(self, k: int, step: int) -> dict[str, Any]:
        """Run ``k``'s ω for its next episode: uniform at first, then around a candidate."""
        box, rng = self.box, self.draws[k]
        if step < self.config.learning_starts:
            self.omega[k] = rng.uniform(box.low, box.high)
        else:
            self.candidates.restart(k, rng)
            j = self.candidates.select(k, rng)
            with torch.no_grad():
                centre = self.candidates.values()[k, j].cpu().numpy().astype(np.float64)
            self.omega[k] = np.clip(centre + rng.normal(0, self.omega_std), box.low, box.high)
        return dict(zip(box.names, self.omega[k].tolist()))

    def observe(self, obs, actions, rewards, next_obs, terminated, infos) -> None:
        self.buffer.add(
            obs=obs,
            action=actions,
            reward=rewards,
            next_obs=next_obs,
            terminated=terminated,
            omega=self.omega,
        )

    def update(self, step: int) -> dict[str, torch.Tensor]:
        size, agent = self.config.batch_size, self.agent
        draws = {"idx": self.buffer.draw(size)}
        draws["eps_omega"] = agent.draw(size, self.box.dim)  # ω's smoothing noise, then a's
        draws["eps"] = agent.draw(size)
        return self._update_with(step, draws, self.candidates.step)

    def _update_with(self, step: int, draws: dict[str, torch.Tensor], descend: Any) -> dict:
        """The update on ``draws``; the worst candidates then descend with ``descend``."""
        agent = self.agent
        with torch.no_grad():
            draws["candidates"] = self.candidates.values()
        out = self._update(step % self.config.policy_frequency == 0, draws)
        losses = {k: v for k, v in out.items() if k.endswith("_loss")}
        if "chosen" in out:  # the worst candidates descend Q1(s, π(s), ω̂) (eager: see below)
            cw, chosen, s, a = self.critic_omega, out["chosen"], out["obs"], out["action"]
            index = chosen.view(-1, 1, 1).expand(-1, 1, self.box.dim)
            worst = self.candidates.values().gather(1, index).expand(-1, s.shape[1], -1)
            loss = agent.critic.q1(torch.cat((s, a, cw(worst)), -1)).mean(-1)
            descend(loss, chosen)
            self.candidates.mark_worst(chosen, self.coeff)
            losses["omega_loss"] = loss.detach()
        return losses

    def _compute(self, update_actor: bool, x: dict[str, torch.Tensor]) -> dict:
        """The device work of an update (``graphs.Update`` may capture it): the critics, and the
        actor against each run's worst candidate. The candidates' own step follows eagerly
        (which of them steps varies; a graph replays fixed work)."""
        agent, cw = self.agent, self.critic_omega
        data = self.buffer.gather(x["idx"])
        # critic: TD3's target with smoothing noise on the next action *and* on ω
        noise = torch.maximum(
            torch.minimum(x["eps_omega"] * self.noise_scale, self.noise_clip), -self.noise_clip
        )
        next_w = torch.maximum(
            torch.minimum(data["omega"] + noise, self.omega_high), self.omega_low
        )
        y = agent.td_target(data, x["eps"], next_cond=cw(next_w))
        s = data["obs"]
        losses = {"critic_loss": agent.critic_step(s, data["action"], y, cond=cw(data["omega"]))}
        if not update_actor:
            return losses
        with torch.no_grad():  # each run's worst candidate: the lowest mean Q1(s, π(s), ω̂)
            a, w = agent.actor(s), x["candidates"]
            k, n, b = w.shape[0], w.shape[1], s.shape[1]
            xs = torch.cat(
                (s.repeat(1, n, 1), a.repeat(1, n, 1), cw(w).repeat_interleave(b, 1)), dim=2
            )
            q = agent.critic.q1(xs).view(k, n, b).mean(2)
            chosen = n - 1 - torch.argmin(q.flip(1), dim=1)  # ties: the last, as the authors
            worst = w.gather(1, chosen.view(-1, 1, 1).expand(-1, 1, w.shape[2])).expand(-1, b, -1)
        losses["actor_loss"] = agent.actor_step(s, cond=cw(worst))
        agent.soft_update()
        return {**losses, "chosen": chosen, "obs": s, "action": a}

    # -- the device-resident loop (``rrls.agents.resident``, the twin): acting, storing and
    # updating as TD3's, each episode's ω chosen on the device as the episode begins (the
    # twin's ``set_points`` writes it), every random input drawn a block of steps ahead
    def draw_ahead(self, steps: int) -> dict[str, torch.Tensor]:
        """TD3's draws, and per step and run from its own ``".ahead"`` streams: ω's smoothing
        noise, and what a beginning episode draws (a uniform ω, the candidate, its noise, the
        restarted candidates' uniforms)."""
        k, n, dim = len(self.run_seeds), self.config.hatomega_number, self.box.dim
        size = self.config.batch_size
        draws = super().draw_ahead(steps)
        normal = np.stack(
            [g.standard_normal((steps, size * dim + dim)) for g in self._ahead()["omega"]], 1
        )
        uniform = np.stack(
            [g.random((steps, dim + 1 + 2 * n * dim)) for g in self._ahead()["episode"]], 1
        )

        def tensor(x: np.ndarray, *shape: int) -> torch.Tensor:
            as32 = torch.from_numpy(np.ascontiguousarray(x, dtype=np.float32))
            return as32.to(self.agent.device).view(steps, k, *shape)

        draws["eps_omega"] = tensor(normal[..., : size * dim], size, dim)
        draws["omega_noise"] = tensor(normal[..., size * dim :], dim)
        draws["omega_uniform"] = tensor(uniform[..., :dim], dim)
        draws["pick"] = tensor(uniform[..., dim])
        draws["close_u"] = tensor(uniform[..., dim + 1 : dim + 1 + n * dim], n, dim)
        draws["rare_u"] = tensor(uniform[..., dim + 1 + n * dim :], n, dim)
        return draws

    def _ahead(self) -> dict[str, NumpyGenerators]:
        """The streams of ``draw_ahead``'s own draws, made on first use."""
        if self.episode_ahead is None:
            names = ("omega", "episode")
            self.episode_ahead = {n: NumpyGenerators(self.run_seeds, f"{n}.ahead") for n in names}
        return self.episode_ahead

    def _act_on_device(self, variant: None, x: dict[str, torch.Tensor]) -> torch.Tensor:
        """TD3's, unclipped with ``clip_exploration=False`` (as ``act``)."""
        if self.config.clip_exploration:
            return super()._act_on_device(variant, x)
        with torch.no_grad():
            return self.agent.actor(x["obs"].unsqueeze(1)).squeeze(1) + x["noise"]

    def put(self, obs, actions, rewards, next_obs, terminated) -> None:
        at = {"obs": obs, "action": actions, "next_obs": next_obs, "omega": self.omega_t}
        self.buffer.put(reward=rewards, terminated=terminated, **at)

    def update_drawn(self, step: int, draws: dict[str, torch.Tensor]) -> dict[str, torch.Tensor]:
        names = ("idx", "eps", "eps_omega")
        return self._update_with(step, {n: draws[n] for n in names}, self.candidates.step_masked)

    def begin_episodes(
        self, begins: torch.Tensor, lengths: torch.Tensor | None, step: int, row: dict
    ) -> torch.Tensor:
        """``episode_options`` on the device for the runs of ``begins`` (``(K,)``; ``lengths``:
        the episodes that just ended, for the worst candidates' average, None at the start):
        their ω as ``episode_options`` draws it; every run's ω, ``(K, dim)``, to write."""
        self._to_device()
        if lengths is not None:
            self.coeff.copy_(torch.where(begins, 1.0 / lengths.clamp(min=1).double(), self.coeff))
        if step < self.config.learning_starts:
            omega = self.omega_low + row["omega_uniform"] * (self.omega_high - self.omega_low)
        else:
            c = self.candidates
            c.restart_masked(begins, row["close_u"], row["rare_u"])
            chosen = c.select_drawn(begins, row["pick"])
            with torch.no_grad():
                centre = c.values()[torch.arange(len(chosen), device=chosen.device), chosen]
            noise = row["omega_noise"] * self.omega_std_t
            omega = torch.minimum(torch.maximum(centre + noise, self.omega_low), self.omega_high)
        self.omega_t = torch.where(begins[:, None], omega, self.omega_t)
        return self.omega_t

    def episode_points(self) -> torch.Tensor:
        """Every run's ω of the episode in progress (a resumed run starts it again there)."""
        self._to_device()
        return self.omega_t

    def _to_device(self) -> None:
        """Once, as the resident loop starts: the candidates as rows, ω on the device."""
        if self.on_device:
            return
        self.on_device = True
        self.candidates.to_storage()
        self.omega_t, self.omega_std_t = (
            torch.as_tensor(x, dtype=torch.float32, device=self.agent.device)
            for x in (self.omega, self.omega_std)
        )

    def episode_end(self, k: int, episode_return: float, length: int) -> dict[str, float]:
        if not self.on_device:  # on the device: set as the episode ended (begin_episodes)
            self.coeff[k] = 1.0 / max(1, length)
        with torch.no_grad():
            values = self.candidates.values()[k].cpu().numpy()
        probabilities = self.candidates.probabilities[k].cpu().numpy()
        extra = {f"m2td3/probability_{j}": p for j, p in enumerate(probabilities)}
        for j in range(len(values)):
            for i, name in enumerate(self.box.names):
                extra[f"m2td3/hatomega_{j}_{name}"] = values[j, i]
        return extra

    def state_dict(self) -> dict[str, Any]:
        return {
            **super().state_dict(),
            "candidates": self.candidates.state_dict(),
            "draws": self.draws.state_dict(),
            "coeff": self.coeff.clone(),
            "omega": self.omega_t.double().cpu() if self.on_device else torch.as_tensor(self.omega),
            **{f"{n}_ahead": g.state_dict() for n, g in (self.episode_ahead or {}).items()},
        }

    def load_state_dict(self, state: dict[str, Any]) -> None:
        super().load_state_dict(state)
        self.candidates.load_state_dict(state["candidates"])
        self.draws.load_state_dict(state["draws"])
        self.coeff.copy_(state["coeff"])
        self.omega[:] = state["omega"].numpy()
        if "omega_ahead" in state:  # a run of the resident loop
            for name, streams in self._ahead().items():
                streams.load_state_dict(state[f"{name}_ahead"])
