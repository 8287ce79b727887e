"""rrls's TD3 update against a plain CleanRL-style one (separate ``nn.Linear`` critics, F.mse_loss,
torch.optim.Adam) started from the same weights on the same batches: the batched-module core
must compute TD3 itself, not something close to it."""

from __future__ import annotations

import numpy as np
import pytest

torch = pytest.importorskip("torch")
F = torch.nn.functional

from rrls.agents.algos.td3 import Config, Learner  # noqa: E402
from rrls.agents.envs import task_env  # noqa: E402
from rrls.agents.streams import RunSeeds  # noqa: E402


def _plain(layer, j=None):
    w = layer.weight[0] if j is None else layer.weight[0, j]
    b = layer.bias[0, 0] if j is None else layer.bias[0, j, 0]
    m = torch.nn.Linear(w.shape[0], w.shape[1])
    m.weight.data, m.bias.data = w.detach().t().clone(), b.detach().clone()
    return m


def test_td3_update_equals_a_plain_cleanrl_style_update():
    env = task_env("invertedpendulum")[0]
    learner = Learner(env, Config(learning_rate=1e-3), [RunSeeds(0)], "cpu")
    rng = np.random.default_rng(0)
    for _ in range(1000):
        learner.observe(
            rng.normal(size=(1, 4)),
            [rng.uniform(-3, 3, 1).astype(np.float32)],
            rng.normal(size=1),
            rng.normal(size=(1, 4)),
            np.array([rng.random() < 0.1]),
            [{}],
        )
    ag = learner.agent
    actor, actor_t = (
        torch.nn.ModuleList(map(_plain, m.layers)) for m in (ag.actor, ag.actor_target)
    )
    critics = [torch.nn.ModuleList(_plain(x, j) for x in ag.critic.layers) for j in (0, 1)]
    targets = [torch.nn.ModuleList(_plain(x, j) for x in ag.critic_target.layers) for j in (0, 1)]
    scale, bias = ag.actor.action_scale, ag.actor.action_bias

    def net(m, x):
        for layer in m[:-1]:
            x = F.relu(layer(x))
        return m[-1](x)

    q_opt = torch.optim.Adam([p for m in critics for p in m.parameters()], lr=1e-3)
    pi_opt = torch.optim.Adam(actor.parameters(), lr=1e-3)
    for step in range(1, 7):
        idx, eps = learner.buffer.draw(256), ag.draw(256)
        d = {k: v[0] for k, v in learner.buffer.gather(idx).items()}
        with torch.no_grad():
            noise = (eps[0] * 0.2).clamp(-0.5, 0.5) * scale
            a2 = (torch.tanh(net(actor_t, d["next_obs"])) * scale + bias + noise).clamp(-3, 3)
            x2 = torch.cat([d["next_obs"], a2], -1)
            q2 = torch.min(net(targets[0], x2), net(targets[1], x2)).squeeze(-1)
            y = d["reward"] + 0.99 * (1 - d["terminated"]) * q2
        x = torch.cat([d["obs"], d["action"]], -1)
        loss = sum(F.mse_loss(net(q, x).squeeze(-1), y) for q in critics)
        q_opt.zero_grad()
        loss.backward()
        q_opt.step()
        if step % 2 == 0:
            a = torch.tanh(net(actor, d["obs"])) * scale + bias
            pi_loss = -net(critics[0], torch.cat([d["obs"], a], -1)).mean()
            pi_opt.zero_grad()
            pi_loss.backward()
            pi_opt.step()
            with torch.no_grad():
                for src, dst in zip((actor, *critics), (actor_t, *targets)):
                    for p, tp in zip(src.parameters(), dst.parameters()):
                        tp.lerp_(p, 0.005)
        losses = learner._compute(step % 2 == 0, {"idx": idx, "eps": eps})
        assert float(losses["critic_loss"][0]) == pytest.approx(loss.item(), rel=1e-5)
        if step % 2 == 0:
            assert float(losses["actor_loss"][0]) == pytest.approx(pi_loss.item(), rel=1e-4)
    pairs = [(ag.actor, actor, None), (ag.actor_target, actor_t, None)]
    pairs += [(ag.critic, critics[j], j) for j in (0, 1)]
    for ours, plain, j in pairs:
        for layer, ref in zip(ours.layers, plain):
            np.testing.assert_allclose(
                _plain(layer, j).weight.detach(), ref.weight.detach(), atol=1e-4
            )
