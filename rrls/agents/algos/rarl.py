"""RARL (Pinto et al. 2017, "Robust Adversarial Reinforcement Learning"), on the TD3 core.

A protagonist and an adversary, both TD3 learners, play the zero-sum game of
``DynamicAdversarial``: each step the adversary picks the perturbation and the protagonist acts;
the protagonist maximises the reward, the adversary ``-reward``. Both act at every step.

- **Schedule** (``schedule``). ``simultaneous`` (the default, what the presets and the shipped
  references run): both players take one TD3 update at every env step after the warm-up, the
  protagonist's first, as the RRLS authors' own trainer does (``SuReLI/TCRMDP``,
  ``src/td3/trainer.py:418-431``, ``TrainerAdversarial._update_agents``, called every step at
  ``trainer.py:224-225`` and run by ``src/main_rarl.py`` on RRLS's ``DynamicAdversarial``).
  ``alternating`` is Pinto et al.'s Algorithm 1: phases of ``phase_steps`` env steps during
  which only the protagonist learns (the adversary plays its current policy), then as many
  during which only the adversary learns. RARL's reference code (``lerrel/rllab-adv``,
  ``train_adversary.py``) alternates ``n_pro_itr = n_adv_itr = 1`` TRPO iteration per player,
  each on a fresh batch of ``batch_size = 4000`` env steps with both players acting; here a
  phase is those 4 000 env steps, each followed by one update of the learning player.
- **Set.** By default the paper's benchmark set (RRLS §5 trains every baseline on the 3D
  parameter set, 2D on InvertedPendulum): the adversary chooses the physical parameters every
  step. ``--uncertainty rarl`` gives RARL's own game, forces on named bodies (RRLS Table 3).
- **Phases.** RARL's reference code (``lerrel/rllab-adv``, ``train_adversary.py``) alternates
  ``n_pro_itr = n_adv_itr = 1`` TRPO iteration per player, each on a fresh batch of
  ``batch_size = 4000`` env steps collected with both players acting; here a phase is those
  4 000 env steps, each followed by one off-policy update of the learning player.
- **Rate limit.** ``rate_limit=R`` (``rrls train --algo rarl --rate-limit R``) plays
  Time-Constrained Robust MDPs (Zouitine et al., NeurIPS 2024) as the authors' code does
  (``SuReLI/TCRMDP``, ``src/tc_mdp.py``; :mod:`rrls.wrappers.tc_rmdp`): the adversary moves
  every parameter by ``a · R`` per step in raw units (``ψ ← clip(ψ + a · R, box)``; the
  authors train with ``R = 0.001``), episodes start uniformly in the box, the adversary
  observes ``[ψ01, s]`` and, ``omniscient`` (the authors' default), the protagonist's action of
  the step (``trainer.py:369-414``; for a stored transition's next state, the protagonist's
  noise-free action there, where the authors draw a fresh noisy one). The protagonist is the
  paper's Vanilla (``s``), Stacked (``--observe stacked``, the last ``--history`` states and
  actions) or Oracle (``--observe oracle``, ``s`` and ψ01). ``--rate-game target`` is rrls's
  earlier game (``R`` in normalised units towards a target point). The saved policies record
  the game, so the dynamic and static evaluations replay it.
- The final adversary is saved (``adversary.npz``) for the dynamic evaluation (paper Table 6).
- **On the MuJoCo Warp twin** (``WarpTwin(..., adversary=True)``: the adversary's forces or
  parameters written per world inside the step) the game stays on the device
  (``rrls.agents.learner.DeviceLearnerProtocol``). ``act_tensor`` returns the joint action,
  the protagonist's then the adversary's, which the twin splits (the adversary's columns
  become each world's point); ``put`` stores each player's part, the adversary's with
  ``-reward``; ``update_drawn`` is ``update`` on drawn inputs (the same players, in the same
  order). TC-RMDP's game stays on the CPU (its parameters move on the host).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import torch

from rrls.agents.algos.td3 import TD3, TD3Config
from rrls.agents.envs import task_env
from rrls.agents.graphs import Update
from rrls.agents.hparams import hp
from rrls.agents.learner import Learner as _Learner
from rrls.agents.nets import to_mlp_policy
from rrls.agents.replay import ReplayBuffer, transition_fields
from rrls.agents.streams import NumpyGenerators, RunSeeds
from rrls.wrappers.tc_rmdp import MAX_HISTORY, OBSERVE, RATE_GAMES

SCHEDULES = ("simultaneous", "alternating")


@dataclass
class Config(TD3Config):
    """TD3's table for both players, plus when each one learns."""

    schedule: str = hp(
        "simultaneous",
        "when the players learn: simultaneous (both every env step, as the RRLS authors' "
        "trainer, SuReLI/TCRMDP src/td3/trainer.py:418-431) or alternating (Pinto et al.'s "
        "phases of --phase-steps env steps: protagonist, then adversary, ...)",
        choices=list(SCHEDULES),
    )
    phase_steps: int = hp(4000, "--schedule alternating: env steps per phase", most=10**12)
    rate_limit: float | None = hp(
        None,
        "TC-RMDP's time-constrained adversary: each step it moves every parameter by at most "
        "this much, in raw parameter units (psi <- clip(psi + a * R, box), a in [-1, 1]; the "
        "authors train with 0.001); default: none, RARL's unconstrained game",
    )
    rate_game: str | None = hp(
        None,
        "the rate-limited game: tc (TC-RMDP's, as its authors play it; the default) or target "
        "(rrls's earlier game: R in [-1, 1]-normalised units towards a target point, episodes "
        "starting at the nominal point, both players seeing the state)",
        choices=list(RATE_GAMES),
    )
    observe: str | None = hp(
        None,
        "TC-RMDP's protagonist: vanilla (the state; the default), stacked (the last --history "
        "states and actions too) or oracle (the state and the parameters in [0, 1])",
        choices=list(OBSERVE),
    )
    history: int | None = hp(
        None, "--observe stacked: states and actions kept (default 1)", most=MAX_HISTORY
    )
    omniscient: bool | None = hp(
        None,
        "TC-RMDP's adversary also observes the protagonist's action of the step (default: on, "
        "as in the authors' training scripts)",
    )

    def __post_init__(self) -> None:
        super().__post_init__()
        if self.schedule not in SCHEDULES:
            raise ValueError(
                f"schedule must be one of {', '.join(SCHEDULES)}, got {self.schedule!r}"
            )
        if self.phase_steps < 1:
            raise ValueError(f"phase_steps must be >= 1, got {self.phase_steps}")
        if self.rate_limit is not None and not (
            isinstance(self.rate_limit, (int, float))
            and not isinstance(self.rate_limit, bool)
            and 0 < self.rate_limit < float("inf")
        ):
            raise ValueError(
                f"rate_limit must be a finite number > 0 (raw parameter units per step), "
                f"got {self.rate_limit!r}"
            )
        if self.rate_game not in (None, *RATE_GAMES):
            raise ValueError(
                f"rate_game must be one of {', '.join(RATE_GAMES)}, got {self.rate_game!r}"
            )
        if self.observe not in (None, *OBSERVE):
            raise ValueError(f"observe must be one of {', '.join(OBSERVE)}, got {self.observe!r}")
        h = self.history
        if h is not None and (isinstance(h, bool) or not isinstance(h, int) or h < 1):
            raise ValueError(f"history must be an integer >= 1, got {h!r}")
        if self.rate_game is not None and self.rate_limit is None:
            raise ValueError(f"rate_game={self.rate_game!r} needs rate_limit (--rate-limit R)")
        tc_only = {
            "observe": self.observe not in (None, "vanilla"),
            "history": h is not None,
            "omniscient": self.omniscient is not None,
        }
        for name in [n for n, given in tc_only.items() if given and not self.tc]:
            raise ValueError(
                f"{name}={getattr(self, name)!r} applies to TC-RMDP's game: give rate_limit "
                "(--rate-limit R) with rate_game tc"
            )
        if h is not None and self.observe != "stacked":
            raise ValueError(f"history={h!r} applies to observe='stacked', got {self.observe!r}")

    @property
    def tc(self) -> bool:
        """Whether the game is TC-RMDP's (a rate limit, rate_game tc or default)."""
        return self.rate_limit is not None and (self.rate_game or "tc") == "tc"


def make_env(task: str, uncertainty: Any, config: Config, paper: bool = False) -> Any:
    """The two-player game over the set: parameters (``1d/2d/3d``) or forces (``rarl``), the
    adversary's moves rate-limited if ``config.rate_limit`` is set (TC-RMDP)."""
    from rrls.envs import resolve
    from rrls.wrappers import DynamicAdversarial

    if config.observe == "oracle" and resolve(task, uncertainty).family == "force":
        raise ValueError(
            "observe='oracle' shows the protagonist the parameters it is evaluated on; the "
            "force set (--uncertainty rarl) is evaluated on parameter sets, whose envs have no "
            "forces: train the oracle on a parameter set (1d, 2d, 3d)"
        )
    return DynamicAdversarial(
        *task_env(task, uncertainty, paper),
        rate_limit=config.rate_limit,
        rate_game=config.rate_game or "tc",
        observe=config.observe or "vanilla",
        history=config.history or 1,
    )


PLAYERS = ("", "adversary.")  # generator names: the protagonist's, the adversary's


class Learner(_Learner):
    """Two TD3 players, one replay buffer each (the adversary's rewards negated), per run."""

    def __init__(self, env: Any, config: Config, seeds: list[RunSeeds], device: Any) -> None:
        n = env.observation_space.shape[0]
        self.spaces = env.action_space.spaces
        self.config = config
        try:  # each player's part of the observation (TC-RMDP: the env's ``views``)
            views = env.get_wrapper_attr("views")
        except AttributeError:
            views = ((0, n), (0, n))
        self.slices = tuple(slice(lo, hi) for lo, hi in views)
        self.omniscient = config.tc and config.omniscient is not False
        extra = self.spaces[0].shape[0] if self.omniscient else 0
        self.obs_dims = (views[0][1] - views[0][0], views[1][1] - views[1][0] + extra)
        self.players = [
            TD3(dim, s.low, s.high, config, seeds, device, name=name)
            for dim, s, name in zip(self.obs_dims, self.spaces, PLAYERS)
        ]
        self.buffers = [
            ReplayBuffer(
                config.buffer_size,
                transition_fields(dim, s.shape),
                device,
                seeds,
                purpose=name + "replay",
            )
            for dim, s, name in zip(self.obs_dims, self.spaces, PLAYERS)
        ]
        self.rngs = [NumpyGenerators(seeds, name + "explore") for name in PLAYERS]
        self._update = Update(self._compute, device)
        self._act: Any = None  # ``act_tensor``'s ``Update``, made on first use
        # the game the policies record (the set: the run's ``uncertainty``); the dynamic
        # evaluation (``evaluate_run_dynamic``) reads it back to replay the same game, the
        # static one the protagonist's view
        self.game: dict[str, Any] = {"game": "adversarial"}
        if config.rate_limit is not None:
            self.game["rate_limit"] = float(config.rate_limit)
            self.game["rate_game"] = config.rate_game or "tc"
        if config.tc:
            self.game.update(env.get_wrapper_attr("view").to_metadata())
            self.game["omniscient"] = self.omniscient

    def _seen(self, i: int, obs: np.ndarray, agent: np.ndarray | None) -> np.ndarray:
        """Player ``i``'s observations (the omniscient adversary's with ``agent``'s actions)."""
        part = np.ascontiguousarray(obs[:, self.slices[i]])
        if i == 1 and self.omniscient:
            part = np.concatenate([part, agent], axis=1)
        return part

    def act(self, obs: np.ndarray) -> list[Any]:
        cfg, per_player = self.config, []
        for i, (player, rngs, space) in enumerate(zip(self.players, self.rngs, self.spaces)):
            sigma = (space.high - space.low) / 2 * cfg.exploration_noise
            noise = np.stack([rng.normal(0.0, sigma) for rng in rngs])
            seen = self._seen(i, obs, per_player[0] if per_player else None)
            action = np.clip(player.act(seen) + noise, space.low, space.high)
            per_player.append(action.astype(np.float32))
        return list(zip(*per_player))

    def observe(self, obs, actions, rewards, next_obs, terminated, infos) -> None:
        # zero-sum: the adversary learns from -reward; truncation bootstraps for both
        agent = np.stack([a[0] for a in actions]).astype(np.float32)
        after = None
        if self.omniscient:  # the protagonist's noise-free action at the next state
            after = self.players[0].act(self._seen(0, next_obs, None)).astype(np.float32)
        for i, (buffer, sign) in enumerate(zip(self.buffers, (1.0, -1.0))):
            buffer.add(
                obs=self._seen(i, obs, agent),
                action=np.stack([a[i] for a in actions]),
                reward=sign * rewards,
                next_obs=self._seen(i, next_obs, after),
                terminated=terminated,
            )

    def learning(self, step: int) -> tuple[int, ...]:
        """The players that learn at ``step``: both (``simultaneous``), or the protagonist in
        its phases and the adversary in its (``alternating``; counted from the first update, so
        the first phase is a whole one)."""
        if self.config.schedule == "simultaneous":
            return (0, 1)
        return ((step - self.config.learning_starts - 1) // self.config.phase_steps % 2,)

    def update(self, step: int) -> dict[str, torch.Tensor]:
        learning, size = self.learning(step), self.config.batch_size
        draws = {}
        for i in learning:  # the protagonist's draws first, as its update comes first
            draws[f"idx{i}"] = self.buffers[i].draw(size)
            draws[f"eps{i}"] = self.players[i].draw(size)
        return self.update_drawn(step, draws)

    def update_drawn(self, step: int, draws: dict[str, torch.Tensor]) -> dict[str, torch.Tensor]:
        """The update of ``step`` on given random inputs (``idx<i>``, ``eps<i>`` of player
        ``i``; those of a player not learning at ``step`` are left unused)."""
        learning = self.learning(step)
        inputs = {f"{name}{i}": draws[f"{name}{i}"] for i in learning for name in ("idx", "eps")}
        return self._update((learning, step % self.config.policy_frequency == 0), inputs)

    # -- the device-resident loop on the twin's force game: acting, storing and updating on
    # device tensors, every random input drawn a block of steps ahead (``docs/algorithms.md``)
    def draw_ahead(self, steps: int) -> dict[str, torch.Tensor]:
        """The next ``steps`` env steps' random inputs, ``(steps, K, ...)`` on the device, for
        both players whether they learn at that step or not (row ``t`` is step ``t``'s):
        exploration noise from their ``"explore"`` streams (the CPU path's), replay indices and
        smoothing noise from their ``".ahead"`` streams."""
        if self.config.tc:
            raise ValueError("TC-RMDP's game moves its parameters on the host: train it on the CPU")
        size, draws = self.config.batch_size, {}
        for i, (player, rngs, space) in enumerate(zip(self.players, self.rngs, self.spaces)):
            sigma = (space.high - space.low) / 2 * self.config.exploration_noise
            noise = np.stack([rng.normal(0.0, sigma, (steps, len(sigma))) for rng in rngs], 1)
            draws[f"noise{i}"] = torch.from_numpy(noise.astype(np.float32)).to(player.device)
            draws[f"idx{i}"] = self.buffers[i].draw_ahead(steps, size)
            draws[f"eps{i}"] = player.draw_ahead(steps, size)
        return draws

    def act_tensor(self, obs: torch.Tensor, draws: dict[str, torch.Tensor]) -> torch.Tensor:
        """Both players' actions on the device, ``(K, obs) -> (K, act + adversary)``: each
        ``clip(π_i(s) + noise_i)`` as ``act``, the protagonist's columns first."""
        if self._act is None:
            self._act = self._update.sibling(self._act_on_device)
        return self._act(None, {"obs": obs, "noise0": draws["noise0"], "noise1": draws["noise1"]})

    def _act_on_device(self, _variant: None, x: dict[str, torch.Tensor]) -> torch.Tensor:
        """``act_tensor``'s device work."""
        parts = []
        with torch.no_grad():
            for i, player in enumerate(self.players):
                seen = x["obs"][:, self.slices[i]].unsqueeze(1)
                action = player.actor(seen).squeeze(1) + x[f"noise{i}"]
                parts.append(action.clamp(player.low, player.high))
        return torch.cat(parts, 1)

    def put(self, obs, actions, rewards, next_obs, terminated) -> None:
        """``observe`` for device tensors: each player's columns of the joint action, the
        adversary's transition with ``-reward`` (zero-sum)."""
        split = self.spaces[0].shape[0]
        parts = (actions[:, :split], actions[:, split:])
        for i, (buffer, sign) in enumerate(zip(self.buffers, (1.0, -1.0))):
            buffer.put(
                obs=obs[:, self.slices[i]],
                action=parts[i],
                reward=sign * rewards,
                next_obs=next_obs[:, self.slices[i]],
                terminated=terminated,
            )

    def _compute(self, variant: tuple[tuple[int, ...], bool], x: dict[str, torch.Tensor]) -> dict:
        """The device work of an update: each learning player's TD3 step, the protagonist's
        first (``trainer.py:428-430``: ``agent.update`` then ``adversary.update``)."""
        learning, update_actor = variant
        losses = {}
        for i in learning:
            player, data = self.players[i], self.buffers[i].gather(x[f"idx{i}"])
            y = player.td_target(data, x[f"eps{i}"])
            name = ("protagonist", "adversary")[i]
            losses[f"{name}_critic_loss"] = player.critic_step(data["obs"], data["action"], y)
            if update_actor:
                losses[f"{name}_actor_loss"] = player.actor_step(data["obs"])
                player.soft_update()
        return losses

    def episode_end(self, k: int, episode_return: float, length: int) -> dict[str, float]:
        return {"charts/adversary_return": -episode_return}

    def state_dict(self) -> dict[str, Any]:
        return {
            "players": [p.state_dict() for p in self.players],
            "buffers": [b.state_dict() for b in self.buffers],
            "explore": [r.state_dict() for r in self.rngs],
        }

    def load_state_dict(self, state: dict[str, Any]) -> None:
        parts = {"players": self.players, "buffers": self.buffers, "explore": self.rngs}
        for key, objects in parts.items():
            for obj, saved in zip(objects, state[key]):
                obj.load_state_dict(saved)

    def export(self, k: int) -> dict[str, Any]:
        return {
            name: to_mlp_policy(p.actor, k, {**self.game, "obs_dim": dim})
            for name, p, dim in zip(("policy", "adversary"), self.players, self.obs_dims)
        }
