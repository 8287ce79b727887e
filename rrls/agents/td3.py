"""TD3 (Fujimoto et al. 2018, "Addressing Function Approximation Error in Actor-Critic Methods").

The paper's non-robust baseline: TD3 trained on the nominal task. The loop below is the whole
algorithm; the update itself lives in ``rrls.agents.core.TD3``. ``train_single_agent`` is shared
with Domain Randomization, which is this same loop on a randomised environment.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from rrls.agents.common import Run, TrainConfig, make_env, metadata, rng_state, set_rng_state
from rrls.agents.core import TD3
from rrls.agents.replay import ReplayBuffer, transition_fields


def train(config: TrainConfig, resume: bool = False) -> Path:
    """Train TD3 on the nominal task; returns the run directory."""
    return train_single_agent(config, make_env(config.task), resume)


def train_single_agent(config: TrainConfig, env: Any, resume: bool = False) -> Path:
    """TD3 on ``env`` (a Gymnasium env without time limit: the loop truncates episodes)."""
    run = Run(config, resume)
    obs_dim = env.observation_space.shape[0]
    low, high = env.action_space.low, env.action_space.high
    act_dim = len(low)
    cfg = config.td3_config()
    agent = TD3(obs_dim, act_dim, low, high, cfg, seed=config.seed, device=config.device)
    buffer = ReplayBuffer(
        min(cfg.buffer_size, config.steps),
        transition_fields(obs_dim, (act_dim,)),
        device=config.device,
        seed=config.seed + 2,
    )
    rng = np.random.default_rng(config.seed)  # exploration noise and the initial random actions
    meta = metadata(config, obs_dim, act_dim)

    state = run.load()
    if state is None:
        obs, _ = env.reset(seed=config.seed)
    else:  # restore everything, then redo the reset the checkpoint was taken before
        agent.load_state_dict(state["agent"])
        buffer.load_state_dict(state["buffer"])
        set_rng_state(rng, state["rng"])
        set_rng_state(env.unwrapped.np_random, state["env_rng"])
        obs, _ = env.reset()

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
            # a truncated transition keeps terminated=0: its target bootstraps from next_obs
            buffer.add(
                obs=obs,
                action=action,
                reward=reward,
                next_obs=next_obs,
                terminated=float(terminated),
            )
            obs = next_obs

            if run.step > cfg.learning_starts:
                losses = agent.update(
                    buffer.sample(cfg.batch_size), update_actor=run.step % cfg.policy_frequency == 0
                )
                if run.step % 1000 == 0:
                    run.log({f"losses/{k}": v.item() for k, v in losses.items()})
            if run.eval_due():
                run.evaluate(agent.actor, meta)

            if terminated or truncated:  # no transition crosses this reset
                run.episode_end(episode_return, episode_length)
                episode_return, episode_length = 0.0, 0
                if run.checkpoint_due():
                    run.save(
                        {
                            "agent": agent.state_dict(),
                            "buffer": buffer.state_dict(),
                            "rng": rng_state(rng),
                            "env_rng": rng_state(env.unwrapped.np_random),
                        }
                    )
                obs, _ = env.reset()
            bar.update(1)
    finally:
        run.close()
    return run.finish(agent.actor, meta, {"steps": run.step, "episodes": run.episodes})
