"""The rollout engine: many (parameter point, seed) episodes in lockstep, on several processes.

Why this shape:

* **Exact.** Every episode is independent: its env is configured exactly as
  ``env.set_params(**point); env.reset(seed=seed)`` on a freshly made env, and stepped until
  terminated or ``max_episode_steps``. Lockstep batching changes only *when* an episode is stepped,
  never its numbers, provided the policy gives each row the same action whatever the batch
  (``rrls.evaluation.policies.BatchInvariant``; our own policy types are). So results do not
  depend on the number of workers or the batch size.
* **Fast.** The policy runs once per step on all live lanes of a worker; finished lanes take the
  next episode; workers are processes (one per core), each with its own envs.
* **Balanced.** The unit of work is one episode, not one chunk: :func:`plan_work` gives every
  worker an equal contiguous share of the rows to run (sizes differ by at most one), and a worker
  whose share is used up steals single rows from the end of the largest share whose owner cannot
  start them soon (:func:`take_row`). So no worker idles while episodes remain, whatever
  ``workers`` and ``n``, and the last episodes are spread over every worker.
* **Nothing lost.** Episodes are saved in fixed chunks of ``CHUNK`` rows (independent of the
  number of workers and of the work split); each finished chunk is written atomically to
  ``out_dir/chunks/``, and a re-run with the same arguments loads them instead of running them.
"""

from __future__ import annotations

import multiprocessing as mp
import os
import sys
import warnings
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

CHUNK = 50  # episodes per saved chunk: the unit of saving and resuming (not of work sharing)
LANES = 64  # live episodes per worker (one policy block)


class PolicyError(ValueError):
    """The policy returned actions of the wrong shape or non-finite values."""


@dataclass
class RolloutSpec:
    """What to roll out: ``points[p]`` × ``seeds[p, e]``, for ``task`` with env family ``kind``."""

    task: str
    kind: str  # "robust" (parameter sets) or "force" (the RARL force set)
    names: tuple[str, ...]
    points: np.ndarray  # (P, d)
    seeds: np.ndarray  # (P, E) uint32
    max_episode_steps: int = 1000
    stack: Any = None  # an EnvStack (disruptors, schedule, context) around each bare env
    paper: bool = False  # the paper's physics (v4 envs, the original's writes)

    @property
    def n_episodes(self) -> int:
        return self.seeds.size

    def row(self, r: int) -> tuple[int, int]:
        """(point, episode) of flat row ``r``; rows are point-major."""
        return divmod(r, self.seeds.shape[1])

    def describe(self, r: int) -> str:
        p, e = self.row(r)
        point = {n: float(v) for n, v in zip(self.names, self.points[p])}
        return f"mesh point {p} {point}, episode {e} (seed {int(self.seeds[p, e])})"


def episode_seeds(seed: int, n_points: int, episodes: int) -> np.ndarray:
    """Seed of episode ``e`` at point ``p``: from ``SeedSequence(seed, spawn_key=(p, e))``.

    Each (point, episode) gets its own stream, independent of how many points or workers there are.
    """
    out = np.empty((n_points, episodes), dtype=np.uint32)
    for p in range(n_points):
        for e in range(episodes):
            out[p, e] = np.random.SeedSequence(seed, spawn_key=(p, e)).generate_state(1)[0]
    return out


# -- one worker ------------------------------------------------------------------------------------
#: envs per (task, family, stack), reused within one evaluation (building is slower than
#: resetting); ``evaluate`` and ``search_worst_case`` empty it when they return
_ENV_CACHE: dict[tuple[str, str, Any, bool], list[Any]] = {}


def make_rollout_envs(spec: RolloutSpec, n: int) -> list[Any]:
    """Bare envs of the spec's family and physics (in the spec's stack of wrappers, if any);
    every lane is reset before use."""
    from rrls.envs import FAMILY_ENVS, paper_class

    envs = _ENV_CACHE.setdefault((spec.task, spec.kind, spec.stack, spec.paper), [])
    cls = FAMILY_ENVS[spec.kind][spec.task]
    if spec.paper:
        cls = paper_class(cls)
    while len(envs) < n:
        envs.append(cls() if spec.stack is None else spec.stack(cls()))
    return envs[:n]


def clear_env_cache() -> None:
    """Close and forget the cached envs (no state survives from one evaluation to the next)."""
    for envs in _ENV_CACHE.values():
        for env in envs:
            env.close()
    _ENV_CACHE.clear()


Finished = list[tuple[int, float, int, bool, bool]]  # (row, return, length, terminated, diverged)


def run_rows(
    spec: RolloutSpec,
    policy: Callable[[np.ndarray], Any],
    next_row: Callable[[int], int],
    on_finished: Callable[[Finished], None],
    lanes: int = LANES,
    fast: bool = True,
    on_step: Callable[[int], None] | None = None,
) -> None:
    """Roll out episodes in lockstep until no lane is live and ``next_row(live)`` returns -1.

    Whenever episodes end, idle lanes ask for rows (``live``: the lanes still running) until one
    is refused, so the batch stays full while rows remain; ``on_finished`` receives the rows
    finished at each step; ``on_step`` the steps within which a lane will surely be free (0 if
    one is already), for work stealing.
    """
    from rrls.evaluation.kernels import make_stepper

    n_lanes = max(1, lanes)
    envs = make_rollout_envs(spec, n_lanes)
    stepper = make_stepper(envs, spec.task, fast=fast)
    act_dim = envs[0].action_space.shape[0]
    obs_dim = envs[0].observation_space.shape[0]

    obs = np.zeros((n_lanes, obs_dim))
    lane_row = np.full(n_lanes, -1)  # flat row index of the lane's episode, -1 = idle
    returns = np.zeros(n_lanes)
    lengths = np.zeros(n_lanes, dtype=np.int64)

    def start(lane: int, row: int) -> None:
        lane_row[lane] = row
        p, e = spec.row(row)
        env = envs[lane]
        env.reset_params()
        if spec.names:
            env.set_params(**dict(zip(spec.names, spec.points[p].tolist())))
        obs[lane], _ = env.reset(seed=int(spec.seeds[p, e]))
        returns[lane] = 0.0
        lengths[lane] = 0
        stepper.reset(lane, obs[lane])

    def fill() -> None:
        """Give idle lanes new rows while ``next_row`` hands some out."""
        for lane in np.flatnonzero(lane_row < 0).tolist():
            row = next_row(int(np.count_nonzero(lane_row >= 0)))
            if row < 0:
                return
            start(lane, row)

    with _quiet_mujoco():
        fill()
        _loop(
            spec,
            policy,
            stepper,
            fill,
            on_finished,
            on_step,
            obs,
            lane_row,
            returns,
            lengths,
            act_dim,
        )


@contextmanager
def _quiet_mujoco() -> Iterator[None]:
    """Keep MuJoCo's instability messages out of stderr and ``MUJOCO_LOG.TXT``.

    Unstable episodes are flagged per row (``diverged``) and summarised once by ``evaluate``.
    """
    import mujoco

    previous = mujoco.get_mju_user_warning()
    mujoco.set_mju_user_warning(lambda msg: None)
    try:
        yield
    finally:
        mujoco.set_mju_user_warning(previous)


def _loop(
    spec: RolloutSpec,
    policy: Callable[[np.ndarray], Any],
    stepper: Any,
    fill: Callable[[], None],
    on_finished: Callable[[Finished], None],
    on_step: Callable[[int], None] | None,
    obs: np.ndarray,
    lane_row: np.ndarray,
    returns: np.ndarray,
    lengths: np.ndarray,
    act_dim: int,
) -> None:
    while (lane_row >= 0).any():
        live = np.flatnonzero(lane_row >= 0)
        actions = np.asarray(policy(obs[live]))
        _check_actions(actions, live, lane_row, lengths, spec, act_dim)
        new_obs, rewards, terminated, diverged = stepper.step(live, actions)
        obs[live] = new_obs
        # a diverged step is not counted: the row keeps the return and length reached before it
        returns[live] += np.where(diverged, 0.0, rewards)
        lengths[live] += ~diverged
        done = np.flatnonzero(terminated | diverged | (lengths[live] >= spec.max_episode_steps))
        if len(done):
            finished = [
                (
                    int(lane_row[live[j]]),
                    float(returns[live[j]]),
                    int(lengths[live[j]]),
                    bool(terminated[j]),
                    bool(diverged[j]),
                )
                for j in done
            ]
            on_finished(finished)
            lane_row[live[done]] = -1
            fill()
        if on_step is not None:
            busy = lane_row >= 0
            on_step(int(spec.max_episode_steps - lengths.max()) if busy.all() else 0)


def _check_actions(
    actions: np.ndarray,
    live: np.ndarray,
    lane_row: np.ndarray,
    lengths: np.ndarray,
    spec: RolloutSpec,
    act_dim: int,
) -> None:
    if actions.dtype.kind not in "biuf":
        r = int(lane_row[live[0]])
        raise PolicyError(
            f"policy returned {actions.dtype} values; actions must be real numbers — at "
            f"{spec.describe(r)}, step {lengths[live[0]]}"
        )
    if actions.shape != (len(live), act_dim):
        r = int(lane_row[live[0]])
        raise PolicyError(
            f"policy returned actions of shape {actions.shape} for {len(live)} observations; "
            f"expected ({len(live)}, {act_dim}) — at {spec.describe(r)}, step {lengths[live[0]]}"
        )
    bad = ~np.isfinite(actions).all(axis=1)
    if bad.any():
        j = int(np.flatnonzero(bad)[0])
        r = int(lane_row[live[j]])
        raise PolicyError(
            f"policy returned non-finite actions {actions[j].tolist()} at {spec.describe(r)}, "
            f"step {lengths[live[j]]}"
        )


@dataclass(frozen=True)
class WorkPlan:
    """How ``n`` rows are split among workers: ``shares[w]`` = (start, stop) offsets, and lanes.

    Why: the unit of saving (a ``CHUNK``) must not be the unit of work (512 rows = 11 chunks
    would keep 5 of 16 workers idle), and one shared counter hands the last wave to whoever asks
    first. Equal shares start every worker with the same load; stealing (:func:`take_row`) evens
    out episodes of different lengths.
    """

    shares: tuple[tuple[int, int], ...]
    lanes: int

    @property
    def workers(self) -> int:
        return len(self.shares)


def plan_work(n: int, workers: int, lanes: int = LANES) -> WorkPlan:
    """Split ``n`` rows into ``min(workers, n)`` contiguous shares whose sizes differ by <= 1.

    Each worker runs ``min(lanes, largest share)`` lanes: no lane is built that would never get an
    episode. The split changes only who runs a row, never its numbers.
    """
    if workers < 1:
        raise ValueError(f"workers must be >= 1, got {workers}")
    workers = max(1, min(workers, n))
    base, extra = divmod(n, workers)
    shares, start = [], 0
    for w in range(workers):
        stop = start + base + (w < extra)
        shares.append((start, stop))
        start = stop
    return WorkPlan(tuple(shares), max(1, min(lanes, -(-n // workers))))


def take_row(bounds: Any, w: int, live: int = 0, horizon: int = 0) -> int:
    """Next row offset for worker ``w`` (running ``live`` lanes), or -1: none for it now.

    ``bounds`` is ``[next_0, stop_0, soon_0, next_1, ...]`` (a shared array, under its lock):
    worker ``v``'s unstarted rows are ``next_v:stop_v``, and within ``soon_v`` steps one of its
    lanes will surely be free (all its lanes are busy while it has rows; an episode ends at
    ``max_episode_steps`` at the latest). A worker takes the front of its own share, then steals
    the last row of the largest share whose owner cannot start it within ``horizon`` steps.
    Why not steal greedily: with equal episode lengths all workers reach the last wave together,
    and whoever asks first would take a full set of lanes from the others' shares (5000 rows on
    16 x 64 lanes: 14 workers with 64, one with 8, one with none), which makes those workers'
    steps slower. A worker with no live lane takes any row left, so none idles while rows remain.
    """
    if bounds[3 * w] < bounds[3 * w + 1]:
        i = bounds[3 * w]
        bounds[3 * w] = i + 1
        return int(i)
    victim, most = -1, 0
    for v in range(len(bounds) // 3):
        left = bounds[3 * v + 1] - bounds[3 * v]
        if left > most and (live == 0 or bounds[3 * v + 2] > horizon):
            victim, most = v, left
    if victim < 0:
        return -1
    bounds[3 * victim + 1] -= 1
    return int(bounds[3 * victim + 1])


def shared_bounds(plan: WorkPlan, max_episode_steps: int) -> list[int]:
    """The initial ``bounds`` of :func:`take_row`: each share, and "not started" as far away."""
    return [i for a, b in plan.shares for i in (a, b, max_episode_steps)]


def steal_horizon(max_episode_steps: int) -> int:
    """Rows whose owner frees a lane within 5 % of an episode are left to it (see take_row)."""
    return max(1, max_episode_steps // 20)


def _worker_main(
    spec: RolloutSpec,
    policy: Callable,
    rows: np.ndarray,
    bounds: Any,
    w: int,
    results: Any,
    lanes: int,
    fast: bool,
    parent: int,
) -> None:
    """A worker process: take rows (own share, then stolen ones), send finished episodes back."""
    _exit_with_parent(parent)
    try:
        try:  # one BLAS thread per process: the processes already use every core
            from threadpoolctl import threadpool_limits

            threadpool_limits(1)
        except ImportError:  # pragma: no cover - threadpoolctl is a dependency
            pass
        if "torch" in sys.modules:
            sys.modules["torch"].set_num_threads(1)

        horizon = steal_horizon(spec.max_episode_steps)

        def next_row(live: int) -> int:
            with bounds.get_lock():
                i = take_row(bounds, w, live, horizon)
            return int(rows[i]) if i >= 0 else -1

        far = [True]  # as published: "no lane of mine frees within the horizon"

        def on_step(soon: int) -> None:
            if (soon > horizon) != far[0]:  # take_row only compares with the horizon
                far[0] = soon > horizon
                bounds[3 * w + 2] = soon

        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # MuJoCo model warnings: the parent reported them
            run_rows(spec, policy, next_row, results.put, lanes, fast, on_step)
        results.put(None)
    except BaseException as err:  # noqa: BLE001 - forwarded to the parent, which re-raises
        results.put(_Failure(err))


def _exit_with_parent(parent: int) -> None:
    """Make this worker die with the evaluation that started it, even after ``kill -9``.

    Linux: ``prctl(PR_SET_PDEATHSIG, SIGKILL)``; elsewhere (or if that fails) a daemon thread
    that polls the parent pid. Either way a worker never outlives its parent blocked on a queue.
    """
    import signal
    import threading
    import time

    if sys.platform.startswith("linux"):
        try:
            import ctypes

            libc = ctypes.CDLL(None, use_errno=True)
            pr_set_pdeathsig = 1
            if libc.prctl(pr_set_pdeathsig, int(signal.SIGKILL), 0, 0, 0) == 0:
                if os.getppid() != parent:  # the parent died before prctl took effect
                    os._exit(1)
                return
        except (OSError, AttributeError):  # pragma: no cover - no libc/prctl: poll instead
            pass

    def watch() -> None:  # pragma: no cover - non-Linux fallback
        while os.getppid() == parent:
            time.sleep(1.0)
        os._exit(1)

    threading.Thread(target=watch, name="rrls-parent-watch", daemon=True).start()


class _Failure:
    """An exception from a worker, carried to the parent (re-raised there with its message)."""

    def __init__(self, err: BaseException) -> None:
        import traceback

        self.err = err if _picklable(err) else RuntimeError(f"{type(err).__name__}: {err}")
        self.trace = "".join(traceback.format_exception(err))


def _picklable(obj: Any) -> bool:
    import pickle

    try:
        pickle.dumps(obj)
    except Exception:  # noqa: BLE001
        return False
    return True


# -- many chunks, many workers, resumable ---------------------------------------------------------
def default_workers() -> int:
    from rrls._proc import cores

    return cores()


def run(
    spec: RolloutSpec,
    policy: Callable[[np.ndarray], Any],
    workers: int | None = None,
    lanes: int = LANES,
    chunk: int = CHUNK,
    chunk_dir: str | Path | None = None,
    progress: bool | None = None,
    fast: bool = True,
) -> dict[str, np.ndarray]:
    """All episodes of ``spec`` as columns; finished chunks are saved to/loaded from ``chunk_dir``.

    Chunks are fixed blocks of ``chunk`` consecutive rows: the unit of saving and resuming. Which
    worker runs which episode does not matter: every row's numbers depend only on its point,
    its seed and the policy.
    """
    from rrls._io import atomic_save_npz

    n = spec.n_episodes
    cols = {
        "return": np.zeros(n),
        "length": np.zeros(n, dtype=np.int64),
        "terminated": np.zeros(n, dtype=bool),
        "diverged": np.zeros(n, dtype=bool),
    }
    n_chunks = -(-n // chunk)
    remaining = np.array([min(chunk, n - c * chunk) for c in range(n_chunks)])
    if chunk_dir is not None:
        chunk_dir = Path(chunk_dir)
        chunk_dir.mkdir(parents=True, exist_ok=True)
        remove_leftovers(chunk_dir)
        for c in range(n_chunks):
            path = chunk_dir / f"{c:06d}.npz"
            if path.exists() and _load_chunk(
                path, cols, slice(c * chunk, c * chunk + remaining[c])
            ):
                remaining[c] = 0
    todo = np.concatenate(
        [np.arange(c * chunk, c * chunk + remaining[c]) for c in range(n_chunks) if remaining[c]]
        or [np.zeros(0, dtype=np.int64)]
    )
    workers = default_workers() if workers is None else int(workers)
    plan = plan_work(len(todo), workers, lanes)
    lanes = plan.lanes

    if len(todo):
        make_rollout_envs(spec, lanes)  # built once here: forked workers inherit them
    bar = _progress_bar(n, progress)
    bar.update(n - len(todo))

    def on_finished(finished: Finished) -> None:
        for row, ret, length, term, div in finished:
            cols["return"][row], cols["length"][row] = ret, length
            cols["terminated"][row], cols["diverged"][row] = term, div
            c = row // chunk
            remaining[c] -= 1
            if remaining[c] == 0 and chunk_dir is not None:
                block = slice(c * chunk, min((c + 1) * chunk, n))
                atomic_save_npz(
                    chunk_dir / f"{c:06d}.npz", **{k: v[block] for k, v in cols.items()}
                )
        bar.update(len(finished))

    try:
        if len(todo) and plan.workers == 1:
            it = iter(todo.tolist())
            run_rows(spec, policy, lambda live: next(it, -1), on_finished, lanes, fast)
        elif len(todo):
            _run_processes(spec, policy, todo, plan, fast, on_finished)
    finally:
        bar.close()
    return cols


def remove_leftovers(chunk_dir: Path) -> list[Path]:
    """Delete the temporary files of chunk writes killed half-way (``.000003.npz.XXXX.tmp``).

    ``evaluate`` holds the directory's lock, so no live writer owns them.
    """
    leftovers = sorted(chunk_dir.glob(".*.tmp"))
    for path in leftovers:
        path.unlink(missing_ok=True)
    return leftovers


def _load_chunk(path: Path, cols: dict[str, np.ndarray], block: slice) -> bool:
    """Fill ``cols[block]`` from a saved chunk; a truncated, empty or malformed file is reported
    by name, removed and recomputed (``False``), never a bare ``BadZipFile``/``EOFError``."""
    size = block.stop - block.start
    try:
        with np.load(path, allow_pickle=False) as f:
            data = {k: np.asarray(f[k]) for k in cols}
        for k, v in data.items():
            if v.shape != (size,) or not np.can_cast(v.dtype, cols[k].dtype, "same_kind"):
                raise ValueError(f"column {k!r} has shape {v.shape} and dtype {v.dtype}")
    except Exception as err:  # noqa: BLE001 - any unreadable content: recompute the chunk
        warnings.warn(
            f"chunk file {path} is unreadable ({type(err).__name__}: {err}); recomputing it",
            stacklevel=3,
        )
        path.unlink(missing_ok=True)
        return False
    for k, v in data.items():
        cols[k][block] = v
    return True


def _run_processes(
    spec: RolloutSpec,
    policy: Callable,
    todo: np.ndarray,
    plan: WorkPlan,
    fast: bool,
    on_finished: Callable[[Finished], None],
) -> None:
    import queue as queue_mod

    # fork shares the policy with the workers without pickling it (lambdas and closures work);
    # spawn (other platforms) pickles it.
    ctx = mp.get_context("fork" if "fork" in mp.get_all_start_methods() else "spawn")
    bounds = ctx.Array("q", shared_bounds(plan, spec.max_episode_steps))
    results = ctx.Queue()
    procs = [
        ctx.Process(
            target=_worker_main,
            args=(spec, policy, todo, bounds, w, results, plan.lanes, fast, os.getpid()),
            daemon=True,
        )
        for w in range(plan.workers)
    ]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)  # fork with threads (3.12+)
        for proc in procs:
            proc.start()
    running = plan.workers
    try:
        while running:
            try:
                msg = results.get(timeout=1.0)
            except queue_mod.Empty:
                dead = [p for p in procs if not p.is_alive() and p.exitcode not in (0, None)]
                if dead:
                    raise RuntimeError(
                        f"an evaluation worker died (exit code {dead[0].exitcode}); "
                        "finished chunks are saved — re-run to resume"
                    ) from None
                continue
            if msg is None:
                running -= 1
            elif isinstance(msg, _Failure):
                raise msg.err
            else:
                on_finished(msg)
    finally:
        for proc in procs:
            if proc.is_alive():
                proc.terminate()
        for proc in procs:
            proc.join()
        results.close()


def _progress_bar(total: int, progress: bool | None) -> Any:
    from tqdm.auto import tqdm

    disable = not sys.stderr.isatty() if progress is None else not progress
    return tqdm(total=total, unit="episode", desc="evaluating", disable=disable, smoothing=0.1)
