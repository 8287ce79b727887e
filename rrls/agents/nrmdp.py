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
from rrls.agents.core import TD3, Player, TD3Config, Update, hp
from rrls.agents.loop import Learner as _Learner
from rrls.agents.networks import rows
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
    """The protagonists' TD3 (whose critics both players use) and the adversaries' policies."""

    def __init__(
        self,
        env: Any,
        config: Config,
        runs: list[TrainConfig],
        rngs: list[np.random.Generator],
    ) -> None:
        obs_dim = env.observation_space.shape[0]
        space = env.action_space.spaces[0]
        self.low, self.high = space.low, space.high
        self.config, self.alpha = config, config.alpha
        seeds, device = [r.seed for r in runs], runs[0].device
        act_dim = len(self.low)
        self.agent = TD3(obs_dim, act_dim, self.low, self.high, config, seeds, device)
        gens = [torch.Generator().manual_seed(s + 1000) for s in seeds]
        self.opponent = Player(
            obs_dim, act_dim, self.low, self.high, config, gens, self.agent.device
        )
        self.buffer = ReplayBuffer(
            min(config.buffer_size, runs[0].steps),
            transition_fields(obs_dim, (act_dim,)),
            device,
            [s + 2 for s in seeds],
        )
        self.actor, self.adversary = self.agent.actor, self.opponent.actor
        self.game = {"game": config.mode, "alpha": config.alpha}
        self.policy_steps = 0
        self._update = Update(self._compute, self.agent.device, runs[0].cuda_graphs)
        self._sources = [rows(p) for p in self.opponent.actor.parameters()]
        self._targets = [rows(p) for p in self.opponent.target.parameters()]

    def act(self, obs: np.ndarray, rngs: list[np.random.Generator], warmup: bool) -> list[Any]:
        if warmup:
            return [
                tuple(rng.uniform(self.low, self.high).astype(np.float32) for _ in range(2))
                for rng in rngs
            ]
        mine = self.agent.explore(obs, rngs)
        theirs = self.opponent.deterministic(obs).astype(np.float32)
        return list(zip(mine, theirs))

    def store(self, obs, actions, rewards, next_obs, terminated, infos) -> None:  # noqa: ANN001
        self.buffer.add(
            obs=obs,
            action=np.stack([info["executed_action"] for info in infos]),
            reward=rewards,
            next_obs=next_obs,
            terminated=terminated,
        )

    @torch.no_grad()
    def target(
        self, batch: dict[str, torch.Tensor], eps: tuple[torch.Tensor, torch.Tensor]
    ) -> torch.Tensor:
        """The critic's target: NR-MDP on the mixed target action, PR-MDP on the mixture."""
        agent, alpha, next_obs = self.agent, self.alpha, batch["next_obs"]
        mine = agent.target_action(agent.actor_target, next_obs, eps[0])
        theirs = agent.target_action(self.opponent.target, next_obs, eps[1])
        if self.config.mode == "nr":
            q = agent.target_q(next_obs, torch.lerp(mine, theirs, alpha), None)
        else:
            q = torch.lerp(
                agent.target_q(next_obs, mine, None), agent.target_q(next_obs, theirs, None), alpha
            )
        return agent.bootstrap(batch["reward"], batch["terminated"], q)

    def update(self, step: int, update_actor: bool) -> dict[str, torch.Tensor]:
        size, turn = self.config.batch_size, None
        if update_actor:
            self.policy_steps += 1
            turn = "adversary" if self.policy_steps % (self.config.ratio + 1) == 0 else "actor"
        draws = {"idx": self.buffer.draw(size)}
        draws.update({"mine": self.agent.draw(size), "theirs": self.agent.draw(size)})
        return self._update(turn, draws)

    def _compute(self, turn: str | None, x: dict[str, torch.Tensor]) -> dict:
        """The device work of an update: the shared critic, then ``turn``'s policy step."""
        agent, alpha, nr = self.agent, self.alpha, self.config.mode == "nr"
        batch = self.buffer.gather(x["idx"])
        s = batch["obs"]
        target = self.target(batch, (x["mine"], x["theirs"]))
        losses = {"critic_loss": agent.update_critic(s, batch["action"], target)}
        if turn is None:
            return losses
        if turn == "adversary":
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

    def episode_end(self, k: int, episode_return: float, length: int) -> dict[str, float]:
        return {"charts/adversary_return": -episode_return}

    def stacked(self) -> dict[str, torch.Tensor]:
        return {**self.agent.stacked("agent"), **self.opponent.stacked("adversary")}

    def shared(self) -> dict[str, torch.Tensor]:
        return {**self.agent.shared("agent"), **self.opponent.shared("adversary")}

    def generators(self) -> dict[str, list[torch.Generator]]:
        return self.agent.generators("agent")

    def buffers(self) -> list[Any]:
        return [self.buffer]

    def extra_state(self, k: int) -> dict[str, Any]:
        return {"policy_steps": self.policy_steps}

    def load_extra_state(self, k: int, state: dict[str, Any]) -> None:
        self.policy_steps = int(state["policy_steps"])
