"""RARL (Pinto et al. 2017, "Robust Adversarial Reinforcement Learning"), on the TD3 core.

A protagonist and an adversary, both TD3, play the zero-sum game of ``DynamicAdversarial``: each
step the adversary picks the perturbation (by default the RARL force set: forces on named bodies;
a parameter set on request) and the protagonist acts. The protagonist maximises the reward, the
adversary ``-reward``. Training alternates phases, as in the paper: for ``phase_steps`` steps only
the protagonist learns (the adversary plays its current policy), then only the adversary.

``train_two_player`` is the loop; NR-MDP runs the same loop on the action-robust game.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from rrls.agents.common import Run, TrainConfig, make_env, metadata, rng_state, set_rng_state
from rrls.agents.core import TD3
from rrls.agents.replay import ReplayBuffer, transition_fields

PHASE_STEPS = 2_000  # env steps per RARL phase (protagonist, then adversary, then ...)


def train(config: TrainConfig, resume: bool = False) -> Path:
    """Train RARL over ``config.uncertainty`` (``rarl``: forces, the default; or ``1d/2d/3d``)."""
    from rrls.envs import get_uncertainty_set
    from rrls.wrappers import DynamicAdversarial

    kind = "force" if config.uncertainty == "rarl" else "robust"
    env = DynamicAdversarial(
        make_env(config.task, kind), get_uncertainty_set(config.task, config.uncertainty)
    )

    def alternate(step: int) -> tuple[bool, bool]:
        protagonist_phase = (step // PHASE_STEPS) % 2 == 0
        return protagonist_phase, not protagonist_phase

    game = {"game": "adversarial", "uncertainty": config.uncertainty}
    return train_two_player(config, env, alternate, resume, game)


def train_two_player(
    config: TrainConfig,
    env: Any,
    schedule: Callable[[int], tuple[bool, bool]],
    resume: bool = False,
    game: dict | None = None,
) -> Path:
    """Two TD3 learners on a two-player env whose action is ``(agent, adversary)``.

    ``schedule(step)`` says which of (protagonist, adversary) updates at that step.
    """
    run = Run(config, resume)
    obs_dim = env.observation_space.shape[0]
    spaces = env.action_space.spaces
    cfg = config.td3_config()
    players, buffers = [], []
    for i, space in enumerate(spaces):
        players.append(
            TD3(
                obs_dim,
                space.shape[0],
                space.low,
                space.high,
                cfg,
                seed=config.seed + 1000 * i,
                device=config.device,
            )
        )
        buffers.append(
            ReplayBuffer(
                min(cfg.buffer_size, config.steps),
                transition_fields(obs_dim, space.shape),
                device=config.device,
                seed=config.seed + 2 + 1000 * i,
            )
        )
    protagonist, adversary = players
    rng = np.random.default_rng(config.seed)
    meta = metadata(config, obs_dim, spaces[0].shape[0])

    state = run.load()
    if state is None:
        obs, _ = env.reset(seed=config.seed)
    else:
        for player, buffer, saved, saved_buffer in zip(
            players, buffers, state["agents"], state["buffers"]
        ):
            player.load_state_dict(saved)
            buffer.load_state_dict(saved_buffer)
        set_rng_state(rng, state["rng"])
        set_rng_state(env.unwrapped.np_random, state["env_rng"])
        obs, _ = env.reset()

    bar = run.progress()
    episode_return, episode_length = 0.0, 0
    try:
        while run.step < config.steps:
            if run.step < cfg.learning_starts:
                actions = [rng.uniform(s.low, s.high).astype(np.float32) for s in spaces]
            else:
                actions = [player.explore(obs, rng) for player in players]
            next_obs, reward, terminated, _, _ = env.step(tuple(actions))
            run.step += 1
            episode_return += reward
            episode_length += 1
            truncated = episode_length >= config.max_episode_steps
            # zero-sum: the adversary learns from -reward; truncation bootstraps for both
            for buffer, action, sign in zip(buffers, actions, (1.0, -1.0)):
                buffer.add(
                    obs=obs,
                    action=action,
                    reward=sign * reward,
                    next_obs=next_obs,
                    terminated=float(terminated),
                )
            obs = next_obs

            if run.step > cfg.learning_starts:
                update_actor = run.step % cfg.policy_frequency == 0
                for name, player, buffer, active in zip(
                    ("protagonist", "adversary"), players, buffers, schedule(run.step)
                ):
                    if active:
                        losses = player.update(buffer.sample(cfg.batch_size), update_actor)
                        if run.step % 1000 == 0:
                            run.log({f"losses/{name}_{k}": v.item() for k, v in losses.items()})
            if run.eval_due():
                run.evaluate(protagonist.actor, meta)

            if terminated or truncated:
                run.episode_end(
                    episode_return, episode_length, **{"charts/adversary_return": -episode_return}
                )
                episode_return, episode_length = 0.0, 0
                if run.checkpoint_due():
                    run.save(
                        {
                            "agents": [p.state_dict() for p in players],
                            "buffers": [b.state_dict() for b in buffers],
                            "rng": rng_state(rng),
                            "env_rng": rng_state(env.unwrapped.np_random),
                        }
                    )
                obs, _ = env.reset()
            bar.update(1)
    finally:
        run.close()
    return run.finish(
        protagonist.actor,
        {**meta, **(game or {})},
        {"steps": run.step, "episodes": run.episodes},
        adversary=adversary.actor,
        adversary_metadata={"role": "adversary"},
    )
