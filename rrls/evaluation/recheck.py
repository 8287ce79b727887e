"""A worst case that resists episode noise, beside the paper's statistic.

The paper's worst case is the lowest of a run's mesh-point means, each over a few episodes
(5 on the paper's mesh of 1 000 points). Where single episodes are chaotic (a HalfCheetah policy
at one point: 6 164, −449, 5 984, 6 274, 5 491), the minimum of 1 000 noisy means is biased low:
it picks the point whose episodes happened to go worst (the winner's curse). Two statistics say
how much of it is noise, and neither replaces the paper's:

- **the rechecked worst case**: the ``worst`` lowest points re-evaluated with ``episodes`` fresh
  episodes each, from seeds independent of the mesh's (``SeedSequence(seed, spawn_key=(STREAM,
  point, episode))``; the mesh uses ``(point, episode)``), and the lowest of those new means.
  Choosing the points with one set of episodes and scoring them with another removes the
  selection bias; the minimum over ``worst`` fresh means keeps a (much smaller) one.
- **a low quantile of the point means** (``quantile``, default the 5th percentile): the return
  a policy keeps on all but the worst 5 % of the set, from the mesh's own episodes.

When the two agree with the paper's minimum, the worst case is a property of the policy; when
the rechecked value is far above it, the minimum was a few unlucky episodes.

>>> Recheck().to_json()
{'worst': 10, 'episodes': 20, 'quantile': 0.05}
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np

from rrls.evaluation.recheck_settings import Recheck

__all__ = ["STREAM", "Recheck", "recheck", "recheck_seeds"]

#: the first spawn-key element of the rechecked episodes' seeds (the mesh's keys have two
#: elements, these three: no seed is shared with the mesh's episodes)
STREAM = 0x7265


def recheck_seeds(seed: int, points: np.ndarray, episodes: int) -> np.ndarray:
    """Seeds of the rechecked episodes of mesh points ``points`` (their mesh indices)."""
    out = np.empty((len(points), episodes), dtype=np.uint32)
    for i, p in enumerate(points):
        for e in range(episodes):
            key = (STREAM, int(p), e)
            out[i, e] = np.random.SeedSequence(seed, spawn_key=key).generate_state(1)[0]
    return out


def recheck(
    policy: Any,
    task: str,
    protocol: Any,
    episodes: Any,
    how: Recheck | None = None,
    workers: int | None = 1,
    progress: bool | None = False,
) -> dict[str, Any]:
    """Recheck a run's worst case: ``episodes`` is its mesh evaluation's table (one row per
    point and episode, ``EvaluationResult.episodes``); the same ``protocol`` plans the points.
    Returns ``worst_case_rechecked`` (the lowest fresh mean), ``worst_case_q`` (the quantile of
    the mesh's point means), the rechecked points and the settings, for ``result.json``."""
    from rrls.evaluation import engine
    from rrls.evaluation.lanes import Rollouts
    from rrls.evaluation.metrics import point_means
    from rrls.evaluation.prepared import prepare

    how = how or Recheck()
    prepared = prepare(policy, task, protocol)
    plan = protocol.plan(task)
    spec = Rollouts.from_plan(plan, protocol)
    means = point_means(episodes)
    if len(means) != len(spec.points):
        raise ValueError(
            f"the evaluation has {len(means)} points, the protocol plans {len(spec.points)}: "
            "recheck a run under the protocol it was evaluated with"
        )
    values = means.to_numpy(dtype=float)
    k = min(how.worst, len(values))
    chosen = np.argsort(values, kind="stable")[:k]  # ties: the lower point index first
    sub = replace(
        spec,
        points=spec.points[chosen],
        seeds=recheck_seeds(protocol.seed, chosen, how.episodes),
    )
    cols = engine.run(sub, prepared, workers=workers, progress=progress)
    fresh = cols["return"].reshape(k, how.episodes).mean(axis=1)
    low = int(np.argmin(fresh))
    return {
        "worst_case_rechecked": float(fresh[low]),
        "worst_case_q": float(np.quantile(values, how.quantile)),
        "recheck": {
            **how.to_json(),
            "points": [int(p) for p in chosen],
            "mesh_means": [float(values[p]) for p in chosen],
            "fresh_means": [float(v) for v in fresh],
        },
    }
