"""NR-MDP and PR-MDP (Tessler, Efroni, Mannor 2019, "Action Robust Reinforcement Learning and
Applications in Continuous Control"), on the TD3 core, following the authors' code
(``tesslerc/ActionRobustRL``, ``ddpg.py``).

A protagonist π and an adversary π̄ share **one critic over the executed action**:

- **NR-MDP** (``mode="nr"``): the env executes ``(1-α) a + α ā``; the critic's target is
  ``r + γ (1-d) min Q'(s', (1-α) π'(s') + α π̄'(s'))``; the protagonist ascends
  ``Q(s, (1-α) π(s) + α π̄'(s))`` and the adversary *descends* ``Q(s, (1-α) π'(s) + α π̄(s))``
  (each with the other player's target network, as the reference).
- **PR-MDP** (``mode="pr"``): the env executes ``ā`` with probability α, else ``a``; the target
  is ``r + γ (1-d) [(1-α) min Q'(s', π'(s')) + α min Q'(s', π̄'(s'))]``; the protagonist ascends
  ``(1-α) Q(s, π(s))``, the adversary descends ``α Q(s, π̄(s))``.
- **Schedule** (the reference's ``--ratio 10``): the critic learns at every update; of every
  ``ratio + 1`` policy steps, one is the adversary's and ``ratio`` are the protagonist's.
- The protagonist explores with noise, the adversary acts without (as the reference); the
  replay stores the executed action.

On the TD3 core, hence different from the DDPG reference (``docs/differences.md``): twin
critics with target smoothing on both players' target actions, TD3's delayed policy steps and
Polyak rate, Gaussian instead of Ornstein-Uhlenbeck exploration, one update per env step after a
25 k-step random warm-up (the reference: 50 updates per 100 steps from the first batch), the
paper's 256-256 networks. The reference evaluates the critic at ``s`` but feeds the actors
``s'`` in the policy losses; here both use ``s`` (the paper's objective). The final adversary is
saved (``adversary.npz``) for the dynamic evaluation (paper Table 6).

On the MuJoCo Warp twin the game stays on the device (``draw_ahead``, ``act_tensor``, ``put``,
``update_drawn``: ``rrls.agents.learner.DeviceLearnerProtocol``): ``act_tensor`` returns the
executed action (``ProbabilisticActionRobust``'s mixture, or for PR-MDP its coin drawn a block
ahead), which the twin steps and the replay stores, and ``update_drawn`` is ``update`` on drawn
inputs (the same losses in the same order); with ``normalize_obs``, the statistics are updated
on the device at every stored state (``PooledStats.update_tensor``: the same parallel update in
float64) and read back only when saved or exported.

Opt-in, two defaults of the reference's ``DDPG`` (``ddpg.py:42``) the TD3 core leaves off:
``normalize_obs`` (its running state standardisation, pooled over features as its code computes
it: ``PooledStats``) and ``critic_weight_decay`` (its Adam L2 term on the critic, 1e-2).
"""

from __future__ import annotations

import copy
from dataclasses import dataclass
from typing import Any

import numpy as np
import torch

from rrls.agents.algos.td3 import Learner as TD3Learner
from rrls.agents.algos.td3 import TD3Config, cat
from rrls.agents.envs import task_env
from rrls.agents.graphs import Update, adam, load_optimizer
from rrls.agents.hparams import hp
from rrls.agents.nets import Actor, NumpyActor, deterministic, polyak, to_mlp_policy
from rrls.agents.streams import Generators, NumpyGenerators, RunSeeds


@dataclass
class Config(TD3Config):
    """TD3's table plus the game's α, the variant and the reference's update ratio."""

    alpha: float = hp(0.1, "the adversary's share of the action (nr) or its probability (pr)")
    mode: str = hp(
        "nr",
        "nr: NR-MDP (mixed action), pr: PR-MDP (adversary acts w.p. alpha)",
        choices=("nr", "pr"),
    )
    ratio: int = hp(10, "protagonist policy steps per adversary policy step (reference: 10)")
    normalize_obs: bool = hp(
        False, "Tessler's running observation standardisation (one mean and variance per run)"
    )
    critic_weight_decay: float = hp(0.0, "Adam's L2 term on the critic (Tessler's DDPG: 1e-2)")

    def __post_init__(self) -> None:
        super().__post_init__()
        if not (np.isfinite(self.critic_weight_decay) and self.critic_weight_decay >= 0):
            raise ValueError(f"critic_weight_decay must be >= 0, got {self.critic_weight_decay}")
        if not (np.isfinite(self.alpha) and 0.0 <= self.alpha <= 1.0):
            raise ValueError(f"alpha must be in [0, 1], got {self.alpha}")
        if self.mode not in ("nr", "pr"):
            raise ValueError(f"mode must be 'nr' or 'pr', got {self.mode!r}")
        if self.ratio < 0:
            raise ValueError(f"ratio must be >= 0, got {self.ratio}")


def make_env(task: str, uncertainty: Any, config: Config, paper: bool = False) -> Any:
    """The nominal task under the action-robust game (the set is only evaluated over)."""
    from rrls.wrappers import ProbabilisticActionRobust

    return ProbabilisticActionRobust(
        task_env(task, paper=paper)[0], alpha=config.alpha, mode=config.mode
    )


class Learner(TD3Learner):
    """TD3's learner (the protagonist: acting, buffer, critic) plus the adversaries' policies.
    ``env``: the game (``make_env``), or a bare env (the twin's), whose box both players share."""

    def __init__(self, env: Any, config: Config, seeds: list[RunSeeds], device: Any) -> None:
        space = getattr(env.action_space, "spaces", (env.action_space,))[0]
        super().__init__(_Protagonist(env, space), config, seeds, device)
        obs_dim, hidden = env.observation_space.shape[0], config.hidden
        init = Generators(seeds, "adversary.init")
        self.opponent = Actor(obs_dim, len(space.low), hidden, space.low, space.high, init)
        self.opponent = self.opponent.to(device)
        self.opponent_target = copy.deepcopy(self.opponent).requires_grad_(False)
        self.opponent_opt = adam(self.opponent.parameters(), config.learning_rate, device)
        self.opponent_targets = [*self.opponent_target.parameters()]
        self.opponent_sources = [*self.opponent.parameters()]
        self.fast = NumpyActor(self.opponent) if self.agent.fast is not None else None
        self.alpha, self.policy_steps = config.alpha, 0
        self.game = {"game": config.mode, "alpha": config.alpha}
        if config.critic_weight_decay:
            critic = self.agent.critic.parameters()
            lr, decay = config.learning_rate, config.critic_weight_decay
            self.agent.critic_opt = adam(critic, lr, device, weight_decay=decay)
        self.stats = PooledStats(len(seeds), device) if config.normalize_obs else None
        self._update = Update(self._compute, device)
        self.seeds, self.coins = seeds, None  # PR-MDP's coins on the device, drawn ahead

    def act(self, obs: np.ndarray) -> list[Any]:
        """The protagonist explores with noise, the adversary acts without (as the reference)."""
        seen = obs if self.stats is None else self.stats.normalize(obs)
        theirs = deterministic(self.opponent, seen, self.fast).astype(np.float32)
        return list(zip(super().act(seen), theirs))

    def observe(self, obs, actions, rewards, next_obs, terminated, infos) -> None:
        executed = np.stack([info["executed_action"] for info in infos])
        super().observe(obs, executed, rewards, next_obs, terminated, infos)
        if self.stats is not None:  # the raw states are stored; the stats follow each one
            self.stats.update(obs)

    def update(self, step: int) -> dict[str, torch.Tensor]:
        size = self.config.batch_size
        draws = {"idx": self.buffer.draw(size)}
        draws.update({"mine": self.agent.draw(size), "theirs": self.agent.draw(size)})
        return self.update_drawn(step, draws)

    def update_drawn(self, step: int, draws: dict[str, torch.Tensor]) -> dict[str, torch.Tensor]:
        """The update of ``step`` on given random inputs (``idx``, ``mine``, ``theirs``): the
        critic, then the turn's policy step (the schedule counts policy steps)."""
        turn = None
        if step % self.config.policy_frequency == 0:
            self.policy_steps += 1
            turn = "adversary" if self.policy_steps % (self.config.ratio + 1) == 0 else "actor"
        return self._update(turn, {name: draws[name] for name in ("idx", "mine", "theirs")})

    # -- the device-resident loop: the executed action, the replay and the updates on the
    # device, every random input drawn a block of steps ahead (``docs/algorithms.md``)
    def draw_ahead(self, steps: int) -> dict[str, torch.Tensor]:
        """The next ``steps`` env steps' random inputs, ``(steps, K, ...)`` on the device: TD3's
        (exploration noise, replay indices), both players' target smoothing noise (one draw of
        ``2 B`` rows a step, split as ``update``'s two draws) and PR-MDP's coin."""
        size, device = self.config.batch_size, self.agent.device
        noise = [rng.normal(0.0, self.sigma, (steps, len(self.sigma))) for rng in self.rngs]
        eps = self.agent.draw_ahead(steps, 2 * size)
        draws = {
            "noise": torch.from_numpy(np.stack(noise, 1).astype(np.float32)).to(device),
            "idx": self.buffer.draw_ahead(steps, size),
            "mine": eps[:, :, :size],
            "theirs": eps[:, :, size:],
        }
        if self.config.mode == "pr":
            if self.coins is None:
                self.coins = NumpyGenerators(self.seeds, "adversary.coin")
            coin = np.stack([rng.random(steps) for rng in self.coins], 1) < self.alpha
            draws["coin"] = torch.from_numpy(coin).to(device)
        return draws

    def act_tensor(self, obs: torch.Tensor, draws: dict[str, torch.Tensor]) -> torch.Tensor:
        """The executed action on the device, ``(K, obs) -> (K, act)``: the protagonist's
        ``clip(π(s) + noise)`` mixed with the adversary's ``π̄(s)`` as the env mixes them."""
        if self._act is None:
            self._act = self._update.sibling(self._act_on_device)
        inputs = {"obs": obs, "noise": draws["noise"]}
        if self.config.mode == "pr":
            inputs["coin"] = draws["coin"]
        return self._act(None, inputs)

    def put(self, obs, actions, rewards, next_obs, terminated) -> None:
        """``observe`` for device tensors: the executed action stored, the stats following."""
        super().put(obs, actions, rewards, next_obs, terminated)
        if self.stats is not None:
            self.stats.update_tensor(obs)

    def _act_on_device(self, _variant: None, x: dict[str, torch.Tensor]) -> torch.Tensor:
        """``act_tensor``'s device work: ``ProbabilisticActionRobust.step``'s executed action."""
        if self.stats is not None:  # both players see the normalised state, as in ``act``
            x = {**x, "obs": self.stats(x["obs"].unsqueeze(1)).squeeze(1)}
        mine = super()._act_on_device(None, x)
        with torch.no_grad():
            theirs = self.opponent(x["obs"].unsqueeze(1)).squeeze(1)
        if self.config.mode == "nr":
            return (1.0 - self.alpha) * mine + self.alpha * theirs
        return torch.where(x["coin"].unsqueeze(1), theirs, mine)

    @torch.no_grad()
    def target(self, data: dict[str, torch.Tensor], eps_mine, eps_theirs) -> torch.Tensor:
        """The critic's target: NR-MDP on the mixed target action, PR-MDP on the mixture."""
        agent, alpha, s2 = self.agent, self.alpha, data["next_obs"]
        mine = agent.target_action(agent.actor_target, s2, eps_mine)
        theirs = agent.target_action(self.opponent_target, s2, eps_theirs)

        def q(action: torch.Tensor) -> torch.Tensor:
            return agent.critic_target(cat(s2, action)).amin(1)

        if self.config.mode == "nr":
            return agent.target(data, q(torch.lerp(mine, theirs, alpha)))
        return agent.target(data, torch.lerp(q(mine), q(theirs), alpha))

    def _compute(self, turn: str | None, x: dict[str, torch.Tensor]) -> dict:
        """The shared critic's step, then ``turn``'s policy step."""
        agent, alpha, nr = self.agent, self.alpha, self.config.mode == "nr"
        data = self.buffer.gather(x["idx"])
        if self.stats is not None:  # normalised when sampled, by the stats of now (the reference)
            seen = {name: self.stats(data[name]) for name in ("obs", "next_obs")}
            data = {**data, **seen}
        s = data["obs"]
        y = self.target(data, x["mine"], x["theirs"])
        losses = {"critic_loss": agent.critic_step(s, data["action"], y)}
        if turn is None:
            return losses
        q1 = agent.critic.q1
        if turn == "adversary":  # descends Q, against the protagonist's target policy
            if nr:
                with torch.no_grad():
                    other = (1 - alpha) * agent.actor_target(s)
                loss = q1(cat(s, other + alpha * self.opponent(s))).mean(-1)
            else:
                loss = alpha * q1(cat(s, self.opponent(s))).mean(-1)
            losses["adversary_loss"] = agent.policy_step(self.opponent, self.opponent_opt, loss)
        else:  # the protagonist ascends Q, against the adversary's target policy
            if nr:
                with torch.no_grad():
                    other = alpha * self.opponent_target(s)
                loss = -q1(cat(s, (1 - alpha) * agent.actor(s) + other)).mean(-1)
            else:
                loss = -(1 - alpha) * q1(cat(s, agent.actor(s))).mean(-1)
            losses["actor_loss"] = agent.policy_step(agent.actor, agent.actor_opt, loss)
        agent.soft_update()
        polyak(self.opponent_targets, self.opponent_sources, self.config.tau)
        return losses

    def episode_end(self, k: int, episode_return: float, length: int) -> dict[str, float]:
        return {"charts/adversary_return": -episode_return}

    def state_dict(self) -> dict[str, Any]:
        return {
            **super().state_dict(),
            "opponent": self.opponent.state_dict(),
            "opponent_target": self.opponent_target.state_dict(),
            "opponent_opt": self.opponent_opt.state_dict(),
            "policy_steps": self.policy_steps,
            **({"obs_stats": self.stats.state_dict()} if self.stats is not None else {}),
        }

    def load_state_dict(self, state: dict[str, Any]) -> None:
        super().load_state_dict(state)
        self.opponent.load_state_dict(state["opponent"])
        self.opponent_target.load_state_dict(state["opponent_target"])
        load_optimizer(self.opponent_opt, state["opponent_opt"])
        self.policy_steps = int(state["policy_steps"])
        if self.stats is not None:
            self.stats.load_state_dict(state["obs_stats"])

    def export(self, k: int) -> dict[str, Any]:
        """Run ``k``'s two policies; with ``normalize_obs``, the standardisation folded into
        their first layers (``MLPPolicy`` stays a plain MLP of the raw observation)."""
        policies = {
            "policy": to_mlp_policy(self.agent.actor, k, self.game),
            "adversary": to_mlp_policy(self.opponent, k, self.game),
        }
        if self.stats is not None:
            for name, policy in policies.items():
                policies[name] = self.stats.fold(policy, k)
        return policies


class PooledStats:
    """Tessler's observation statistics, as his code computes them, one set per run.

    His ``RunningMeanStd`` (count 1e-4, mean 0, variance 1; ``utils.py:47-53``) is updated with
    each stored state alone (``ddpg.py``, ``store_transition``: ``obs_rms.update(state[b])``), and
    ``update`` takes the moments along axis 0 of that 1-D state (``utils.py:55-58``): so the mean
    and variance are **pooled over every feature** of every stored state, and every feature is
    shifted and scaled alike, ``(s - mean) / sqrt(var)`` (``ddpg.py:28-31``), at acting and when a
    batch is sampled. Kept as his code has it, not per feature.
    """

    def __init__(self, runs: int, device: Any) -> None:
        self.mean, self.var = np.zeros(runs), np.ones(runs)
        self.count = np.full(runs, 1e-4)
        self.shift = torch.zeros(runs, 1, 1, device=device)
        self.scale = torch.ones(runs, 1, 1, device=device)
        self.moments: torch.Tensor | None = None  # (mean, var, count) on the device, once used
        self._sync()

    def update(self, obs: np.ndarray) -> None:
        """Fold one stored state per run (``(K, obs)``) in: Chan et al.'s parallel update."""
        obs = np.asarray(obs, np.float32)
        n = obs.shape[1]
        batch_mean, batch_var = obs.mean(1, dtype=np.float64), obs.var(1, dtype=np.float64)
        delta, total = batch_mean - self.mean, self.count + n
        m2 = self.var * self.count + batch_var * n + delta**2 * self.count * n / total
        self.mean, self.var, self.count = self.mean + delta * n / total, m2 / total, total
        self._sync()

    def update_tensor(self, obs: torch.Tensor) -> None:
        """``update`` for ``(K, obs)`` device tensors (the device-resident loop): the same
        parallel update in float64 on the device, the host's copies following on ``pull``."""
        if self.moments is None:
            moments = np.stack([self.mean, self.var, self.count])
            self.moments = torch.from_numpy(moments).to(self.shift.device)
        seen, n = obs.double(), obs.shape[1]
        batch_mean, batch_var = seen.mean(1), seen.var(1, unbiased=False)
        mean, var, count = self.moments
        delta, total = batch_mean - mean, count + n
        m2 = var * count + batch_var * n + delta**2 * count * n / total
        self.moments = torch.stack([mean + delta * n / total, m2 / total, total])
        self.shift.copy_(self.moments[0].float().view(-1, 1, 1))
        self.scale.copy_(self.moments[1].float().sqrt().view(-1, 1, 1))

    def pull(self) -> None:
        """The host's copies of the device's statistics (one read; none if never used)."""
        if self.moments is not None:
            self.mean, self.var, self.count = self.moments.cpu().numpy().copy()
            self._sync()

    def _sync(self) -> None:
        mean, std = self.mean.astype(np.float32), np.sqrt(self.var.astype(np.float32))
        self.shift.copy_(torch.from_numpy(mean).view(-1, 1, 1))  # in place: graphs read them
        self.scale.copy_(torch.from_numpy(std).view(-1, 1, 1))
        self.mean32, self.std32 = mean[:, None], std[:, None]

    def normalize(self, obs: np.ndarray) -> np.ndarray:
        """``(K, obs)`` states as the networks see them."""
        self.pull()
        return ((np.asarray(obs, np.float32) - self.mean32) / self.std32).astype(np.float32)

    def __call__(self, obs: torch.Tensor) -> torch.Tensor:
        """``(K, B, obs)`` sampled states as the networks see them."""
        return (obs - self.shift) / self.scale

    def fold(self, policy: Any, k: int) -> Any:
        """``policy`` of the normalised state as a policy of the raw one: ``((s - m) / σ) W + b
        = s (W / σ) + (b - (m / σ) Σ_i W_i)``, in float64 then stored in float32."""
        self.pull()
        m, sd = float(self.mean32[k, 0]), float(self.std32[k, 0])
        w0, b0 = policy.weights[0].astype(np.float64), policy.biases[0].astype(np.float64)
        weights = [w0 / sd, *policy.weights[1:]]
        biases = [b0 - (m / sd) * w0.sum(0), *policy.biases[1:]]
        return type(policy)(  # an MLPPolicy
            weights, biases, policy.action_scale, policy.action_bias, metadata=policy.metadata
        )

    def state_dict(self) -> dict[str, torch.Tensor]:
        self.pull()
        return {n: torch.from_numpy(getattr(self, n).copy()) for n in ("mean", "var", "count")}

    def load_state_dict(self, state: dict[str, torch.Tensor]) -> None:
        for n in ("mean", "var", "count"):
            setattr(self, n, state[n].numpy().astype(np.float64).copy())
        self.moments = None
        self._sync()


class _Protagonist:
    """The env as the protagonist's TD3 learner sees it: its own action space."""

    def __init__(self, env: Any, space: Any) -> None:
        self.observation_space, self.action_space = env.observation_space, space
