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
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import torch

from rrls.agents.common import TrainConfig, task_env
from rrls.agents.core import TD3, Player, TD3Config, hp
from rrls.agents.loop import Learner as _Learner
from rrls.agents.replay import ReplayBuffer, transition_fields


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

    def __post_init__(self) -> None:
        super().__post_init__()
        if not (np.isfinite(self.alpha) and 0.0 <= self.alpha <= 1.0):
            raise ValueError(f"alpha must be in [0, 1], got {self.alpha}")
        if self.mode not in ("nr", "pr"):
            raise ValueError(f"mode must be 'nr' or 'pr', got {self.mode!r}")
        if self.ratio < 0:
            raise ValueError(f"ratio must be >= 0, got {self.ratio}")


def make_env(task: str, uncertainty: str, config: Config) -> Any:
    """The nominal task under the action-robust game (the set is only evaluated over)."""
    from rrls.wrappers import ProbabilisticActionRobust

    return ProbabilisticActionRobust(task_env(task)[0], alpha=config.alpha, mode=config.mode)


class Learner(_Learner):
    """The protagonist's TD3 (whose critic both players use) and the adversary's policy."""

    def __init__(
        self, env: Any, config: Config, run: TrainConfig, rng: np.random.Generator
    ) -> None:
        obs_dim = env.observation_space.shape[0]
        space = env.action_space.spaces[0]
        self.low, self.high = space.low, space.high
        self.config, self.alpha = config, config.alpha
        self.agent = TD3(
            obs_dim, len(self.low), self.low, self.high, config, seed=run.seed, device=run.device
        )
        with torch.random.fork_rng(devices=[]):
            torch.manual_seed(run.seed + 1000)
            self.opponent = Player(
                obs_dim, len(self.low), self.low, self.high, config, self.agent.device
            )
        self.buffer = ReplayBuffer(
            min(config.buffer_size, run.steps),
            transition_fields(obs_dim, (len(self.low),)),
            device=run.device,
            seed=run.seed + 2,
        )
        self.actor, self.adversary = self.agent.actor, self.opponent.actor
        self.game = {"game": config.mode, "alpha": config.alpha}
        self.policy_steps = 0
        self._sources = list(self.opponent.actor.parameters())
        self._targets = list(self.opponent.target.parameters())

    def act(self, obs: np.ndarray, rng: np.random.Generator, warmup: bool) -> tuple:
        if warmup:
            return tuple(rng.uniform(self.low, self.high).astype(np.float32) for _ in range(2))
        return self.agent.explore(obs, rng), self.opponent.act_one(obs).astype(np.float32)

    def store(self, obs, action, reward, next_obs, terminated, info) -> None:  # noqa: ANN001
        self.buffer.add(
            obs=obs,
            action=info["executed_action"],
            reward=reward,
            next_obs=next_obs,
            terminated=float(terminated),
        )

    @torch.no_grad()
    def target(self, batch: dict[str, torch.Tensor]) -> torch.Tensor:
        """The critic's target: NR-MDP on the mixed target action, PR-MDP on the mixture."""
        agent, alpha, next_obs = self.agent, self.alpha, batch["next_obs"]
        mine = agent.target_action(agent.actor_target, next_obs)
        theirs = agent.target_action(self.opponent.target, next_obs)
        if self.config.mode == "nr":
            q = agent.target_q(next_obs, torch.lerp(mine, theirs, alpha), None)
        else:
            q = torch.lerp(
                agent.target_q(next_obs, mine, None), agent.target_q(next_obs, theirs, None), alpha
            )
        return agent.bootstrap(batch["reward"], batch["terminated"], q)

    def update(self, step: int, update_actor: bool) -> dict[str, torch.Tensor]:
        agent, alpha, nr = self.agent, self.alpha, self.config.mode == "nr"
        batch = self.buffer.sample(self.config.batch_size)
        s = batch["obs"]
        losses = {"critic_loss": agent.update_critic(s, batch["action"], self.target(batch))}
        if not update_actor:
            return losses
        self.policy_steps += 1
        if self.policy_steps % (self.config.ratio + 1) == 0:  # the adversary's turn
            if nr:
                other = agent.actor_target.forward_saved(s)[0].mul_(1.0 - alpha)
                loss = agent.policy_step(self.opponent, s, share=alpha, other=other, descend=True)
            else:
                loss = agent.policy_step(self.opponent, s, weight=alpha, descend=True)
            losses["adversary_loss"] = loss
        else:
            if nr:
                other = self.opponent.target.forward_saved(s)[0].mul_(alpha)
                loss = agent.policy_step(agent.player, s, share=1.0 - alpha, other=other)
            else:
                loss = agent.policy_step(agent.player, s, weight=1.0 - alpha)
            losses["actor_loss"] = loss
        agent.update_targets()
        torch._foreach_lerp_(self._targets, self._sources, self.config.tau)
        return losses

    def episode_end(self, episode_return: float, length: int) -> dict[str, float]:
        return {"charts/adversary_return": -episode_return}

    def state_dict(self) -> dict[str, Any]:
        return {
            "agent": self.agent.state_dict(),
            "adversary": self.opponent.state_dict(),
            "buffer": self.buffer.state_dict(),
            "policy_steps": self.policy_steps,
        }

    def load_state_dict(self, state: dict[str, Any]) -> None:
        self.agent.load_state_dict(state["agent"])
        self.opponent.load_state_dict(state["adversary"])
        self.buffer.load_state_dict(state["buffer"])
        self.policy_steps = int(state["policy_steps"])
