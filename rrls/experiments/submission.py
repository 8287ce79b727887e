"""``rrls submit``: put a policy trained anywhere through a benchmark's protocol, as a run.

A submitted policy is evaluated exactly as the benchmark's own runs are (the same set, mesh,
episodes and episode seeds; with an adversary also the dynamic evaluation) and written as a run
directory ``DIR/runs/<name>-<task>-<set>-seed<S>/`` in the layout the result store reads
(``eval/``, ``dynamic.csv``, ``result.json`` last). ``rrls report DIR`` then shows the algorithm
in every table and figure like a baseline. ``result.json`` records where the policy came from
(``submitted``: kind, source, SHA-256 of the file), so a report can say which rows were trained
here and which were brought.

Nothing of the benchmark's spec changes: ``rrls benchmark`` over the same directory neither
trains nor touches a submitted algorithm, and rebuilding the store keeps it.

>>> from rrls.experiments.submission import check_name
>>> check_name("sac-dr")
'sac-dr'
>>> try:
...     check_name("TD3")
... except ValueError as err:
...     print(str(err).split(" (")[0])
--algo 'TD3' is a built-in algorithm
"""

from __future__ import annotations

import json
import re
import shutil
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from rrls.experiments.spec import ALGOS, RunKey, Spec, SpecError
from rrls.physics import is_paper

#: names a submission may not take: the built-in algorithms, their display names, and "paper"
#: (the paper's published numbers in the report)
RESERVED = (*ALGOS, "nr-mdp", "pr-mdp", "prmdp", "paper")
_NAME = re.compile(r"^[A-Za-z][A-Za-z0-9_.+-]{0,39}$")
_NAME_RULE = "a letter, then up to 39 letters, digits or _ . + -"
GAMES = ("adversarial", "nr", "pr")


class SubmitError(ValueError):
    """A submission that cannot be accepted (the CLI prints it on one line, exit status 2)."""


@dataclass(frozen=True)
class Submission:
    """What ``submit`` did: the run directory, its ``result.json`` and whether it evaluated."""

    run_dir: Path
    result: dict[str, Any]
    evaluated: bool  # False: the same policy was already submitted (nothing to do)

    @property
    def worst_case(self) -> float:
        return float(self.result["worst_case"])

    @property
    def average_case(self) -> float:
        return float(self.result["average_case"])


def check_name(name: str) -> str:
    """``name`` if it can name a submitted algorithm, else ``SubmitError`` with the rules."""
    if not isinstance(name, str) or not _NAME.match(name):
        raise SubmitError(f"--algo {name!r} is not a valid algorithm name: {_NAME_RULE}")
    if name.lower() in RESERVED:
        raise SubmitError(
            f"--algo {name!r} is a built-in algorithm (reserved: {', '.join(RESERVED)}); "
            f"choose another name: {_NAME_RULE}"
        )
    return name


def load_spec(bench_dir: str | Path) -> Spec:
    """The benchmark's protocol (``DIR/benchmark.json``), or ``SubmitError`` naming the file."""
    path = Path(bench_dir) / "benchmark.json"
    if not path.is_file():
        raise SubmitError(
            f"{bench_dir} is not a benchmark directory (no benchmark.json): create one with "
            f"`rrls benchmark --out {bench_dir} ...`, or pass --preset to `rrls submit` to "
            "start an empty one with that preset's protocol"
        )
    try:
        return Spec.from_json(json.loads(path.read_text()))
    except (ValueError, TypeError) as err:
        raise SubmitError(f"{path} is not a benchmark spec ({err})") from None


def create_benchmark(
    bench_dir: str | Path, preset: str, tasks: tuple[str, ...], **overrides: Any
) -> Spec:
    """An empty benchmark (no built-in algorithm to train) with ``preset``'s protocol on
    ``tasks`` (``overrides``: ``make_spec``'s options, e.g. ``mesh``, ``episodes``):
    submissions compare against a reference file (``rrls report --reference``), and
    ``rrls benchmark --out DIR --preset P`` (same options) may later add the baselines to it.
    A directory already holding a benchmark is refused."""
    from dataclasses import replace

    from rrls._io import atomic_write_json
    from rrls.experiments.spec import make_spec

    if (Path(bench_dir) / "benchmark.json").exists():
        raise SubmitError(f"{bench_dir} already holds a benchmark (benchmark.json)")
    base = make_spec(preset, tasks=",".join(tasks), **overrides)
    spec = replace(base, algos=())
    atomic_write_json(Path(bench_dir) / "benchmark.json", spec.to_json())
    return spec


def _env_shapes(
    task: str, uncertainty: str, paper: bool = False
) -> tuple[tuple[int, ...], tuple[int, ...], int]:
    """The task's observation and action shapes (on the benchmark's physics: Ant-v4 has 27
    observations, Ant-v5 105), and the set's dimension (one env built)."""
    import gymnasium as gym

    from rrls.envs import resolve

    resolved = resolve(task, uncertainty)
    env = gym.make(f"rrls/robust-{resolved.task}-v0", **({"paper": True} if paper else {}))
    try:
        obs, act = env.observation_space.shape, env.action_space.shape
    finally:
        env.close()
    return tuple(obs), tuple(act), len(resolved.box.names)


def _shape_text(shape: tuple[int, ...]) -> str:
    return "(B, " + ", ".join(map(str, shape)) + ")"


def check_shapes(
    policy: Any, obs_shape: tuple[int, ...], act_shape: tuple[int, ...], what: str, task: str
) -> None:
    """Refuse (``SubmitError``, one line naming both shapes) a policy that does not map the
    task's observations to its actions — before any episode runs."""
    from rrls.evaluation.policies import policy_shapes

    declared = policy_shapes(policy)
    expected = (
        f"{task} has observations {_shape_text(obs_shape)} and actions {_shape_text(act_shape)}"
    )
    if declared is not None and declared != (obs_shape, act_shape):
        raise SubmitError(
            f"the {what} maps observations {_shape_text(declared[0])} to actions "
            f"{_shape_text(declared[1])}, but {expected}"
        )
    probe = np.zeros((2, *obs_shape))
    try:
        out = np.asarray(policy(probe))
    except Exception as err:  # noqa: BLE001 - any failure on the task's observations
        first = (str(err).strip().splitlines() or [type(err).__name__])[0]
        raise SubmitError(
            f"the {what} fails on observations {_shape_text(obs_shape)} ({expected}): {first}"
        ) from None
    if out.shape != (2, *act_shape):
        got = "(B, " + ", ".join(map(str, out.shape[1:])) + ")" if out.ndim else "a scalar"
        raise SubmitError(
            f"the {what} maps observations {_shape_text(obs_shape)} to actions {got}, "
            f"but {expected}"
        )


def _identity(source: dict[str, Any], fingerprint: str) -> str:
    """What "the same policy" means: the file's SHA-256, else its actions on probe inputs."""
    return f"sha256:{source['sha256']}" if source.get("sha256") else f"actions:{fingerprint}"


def submit(
    bench_dir: str | Path,
    algo: str,
    task: str,
    seed: int,
    policy: Any,
    adversary: Any = None,
    overwrite: bool = False,
    *,
    game: str | None = None,
    alpha: float | None = None,
    preset: str | None = None,
    workers: int | None = None,
    progress: bool | None = None,
) -> Submission:
    """Evaluate ``policy`` under ``bench_dir``'s protocol and store it as run ``(algo, task,
    seed)``; ``rrls report bench_dir`` then shows ``algo`` beside the baselines.

    ``policy``: a callable ``obs[B, d] -> act[B, k]``, a torch ``nn.Module``, a
    Stable-Baselines3 model, or a path: an rrls ``.npz``, an ``rrls train`` run directory, an
    SB3 ``.zip``, or ``module:attribute``. **An SB3 zip or ``module:attribute`` runs code** (SB3
    unpickles its classes; importing runs the module): submit only what you trust.
    ``adversary`` (same kinds): also play the dynamic evaluation (paper Table 6) — ``game``
    ``adversarial`` (the adversary picks the benchmark set's parameters every step, actions in
    ``[-1, 1]^dim``), ``nr`` or ``pr`` (action-robust, ``alpha``, default 0.1); by default the
    game an rrls adversary file records, else ``adversarial``.
    The same (algo, task, seed) again with the same policy does nothing; with another policy it
    is refused unless ``overwrite``. ``preset``: if ``bench_dir`` holds no benchmark yet, start
    an empty one with that preset's protocol on ``task``.
    """
    from rrls.evaluation.policies import as_policy, policy_fingerprint, policy_source
    from rrls.evaluation.stack import policy_view
    from rrls.tasks import get_task

    check_name(algo)
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise SubmitError(f"--seed must be an integer >= 0, got {seed!r}")
    seed = int(seed)
    try:
        key = get_task(task).key
    except ValueError as err:
        raise SubmitError(str(err)) from None
    root = Path(bench_dir)
    if preset is not None and not (root / "benchmark.json").exists():
        try:
            spec = create_benchmark(root, preset, (key,))
        except SpecError as err:
            raise SubmitError(str(err)) from None
    else:
        spec = load_spec(root)
    if key not in spec.tasks:
        if spec.algos:  # a benchmark with baselines: only its tasks compare
            raise SubmitError(
                f"task {key!r} is not in the benchmark {root} (its tasks: "
                f"{', '.join(spec.tasks)}); add it with `rrls benchmark --out {root} --tasks "
                f"{','.join((*spec.tasks, key))} ...`"
            )
        spec = _add_task(root, spec, key)  # a submissions-only benchmark grows its tasks
    if game is not None and game not in GAMES:
        raise SubmitError(f"unknown game {game!r}; valid: {', '.join(GAMES)}")
    if adversary is None and (game is not None or alpha is not None):
        raise SubmitError("--game and --alpha need --adversary (the dynamic evaluation)")

    source = policy_source(policy)
    try:
        adapted = as_policy(policy)
    except (TypeError, ValueError, FileNotFoundError) as err:
        raise SubmitError(str(err)) from None
    obs_shape, act_shape, set_dim = _env_shapes(key, spec.uncertainty, is_paper(spec.physics))
    view = policy_view(adapted)  # an rrls TC-RMDP Stacked/Oracle protagonist: what it sees
    seen = obs_shape if view is None else (view.dim(obs_shape[0], act_shape[0]),)
    check_shapes(adapted, seen, act_shape, "policy", key)
    adv = adv_source = None
    adv_obs = obs_shape
    if adversary is not None:
        adv_source = policy_source(adversary)
        try:
            adv = as_policy(adversary)
        except (TypeError, ValueError, FileNotFoundError) as err:
            raise SubmitError(f"--adversary: {err}") from None
        meta = getattr(adv, "metadata", None) or {}
        game = game or meta.get("game") or "adversarial"
        if alpha is None:
            alpha = float(meta.get("alpha", 0.1))
        adv_act = (set_dim,) if game == "adversarial" else act_shape
        if game == "adversarial" and spec.rate_limit is not None and spec.rate_game == "tc":
            # TC-RMDP: [ψ01, s], and the protagonist's action when omniscient (the default)
            omniscient = bool(meta.get("omniscient", True))
            adv_obs = (set_dim + obs_shape[0] + (act_shape[0] if omniscient else 0),)
        check_shapes(adv, adv_obs, adv_act, f"adversary ({game} game)", key)
    fingerprint = policy_fingerprint(adapted, seen[0])
    identity = _identity(source, fingerprint)

    run = RunKey(algo, key, seed).name(spec.uncertainty)
    final = root / "runs" / run
    if (final / "result.json").exists():
        old = json.loads((final / "result.json").read_text())
        record = old.get("submitted")
        if record is None:
            raise SubmitError(f"{final} is a trained run, not a submission; it is never replaced")
        same_adv = (record.get("adversary") or {}).get("identity") == (
            _adv_identity(adv_source, adv, adv_obs[0]) if adv is not None else None
        )
        if record.get("identity") == identity and same_adv:  # the same policy: nothing to do
            return Submission(final, old, evaluated=False)
        if not overwrite:
            raise SubmitError(
                f"{algo}/{key}/seed {seed} was already submitted with another policy "
                f"({record.get('source')}); pass --overwrite to replace it"
            )

    staging = root / "submissions" / ".staging" / f"{run}-{identity.split(':')[1][:12]}"
    staging.mkdir(parents=True, exist_ok=True)
    result = _evaluate(spec, algo, key, seed, adapted, staging, workers, progress)
    if adv is not None:
        result.update(_dynamic(spec, key, adapted, adv, game or "adversarial", alpha, staging))
    result["submitted"] = {
        **source,
        "identity": identity,
        "fingerprint": fingerprint,
        "metadata": _jsonable(getattr(adapted, "metadata", None) or {}),
        "submitted_at": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
        "adversary": None
        if adv is None
        else {
            **(adv_source or {}),
            "identity": _adv_identity(adv_source, adv, adv_obs[0]),
            "game": game,
            "alpha": alpha if game != "adversarial" else None,
        },
    }
    _install(root, staging, final, result)
    return Submission(final, result, evaluated=True)


def _adv_identity(source: dict[str, Any] | None, adv: Any, obs_dim: int) -> str:
    from rrls.evaluation.policies import policy_fingerprint

    return _identity(source or {}, policy_fingerprint(adv, obs_dim))


def _jsonable(meta: dict[str, Any]) -> dict[str, Any]:
    return json.loads(json.dumps(meta, default=str))


def _add_task(root: Path, spec: Spec, key: str) -> Spec:
    from dataclasses import replace

    from rrls._io import atomic_write_json
    from rrls.envs import get_uncertainty_set

    try:
        get_uncertainty_set(key, spec.uncertainty)
    except ValueError as err:
        raise SubmitError(str(err)) from None
    spec = replace(spec, tasks=(*spec.tasks, key))
    atomic_write_json(root / "benchmark.json", spec.to_json())
    return spec


def _evaluate(
    spec: Spec,
    algo: str,
    task: str,
    seed: int,
    policy: Any,
    out: Path,
    workers: int | None,
    progress: bool | None,
) -> dict[str, Any]:
    """The final mesh evaluation of the benchmark's runs (``pipeline``'s), into ``out/eval``."""
    from rrls.evaluation import evaluate

    meta = getattr(policy, "metadata", None) or {}
    result = evaluate(
        policy,
        task,
        spec.uncertainty,
        nb_mesh_dim=spec.mesh,
        episodes=spec.episodes,
        seed=spec.eval_seed,
        workers=workers,
        out_dir=out / "eval",
        paper=is_paper(spec.physics),
        split=spec.split_of(task),
        progress=progress,
    )
    return {
        "algorithm": algo,
        "task": task,
        "uncertainty": spec.uncertainty,
        "train_set": str(meta.get("uncertainty") or "unknown"),
        **({"split": spec.split, **result.split_scores()} if spec.split else {}),
        "seed": seed,
        "steps": int(meta.get("steps") or 0),  # the training budget when the policy records it
        "physics": spec.physics,
        "worst_case": result.worst_case,
        "average_case": result.average_case,
        "versions": result.config.get("versions", {}),
    }


def _dynamic(
    spec: Spec, task: str, policy: Any, adversary: Any, game: str, alpha: float | None, out: Path
) -> dict[str, Any]:
    """The dynamic evaluation as the benchmark's RARL / NR-MDP runs play it (``dynamic.csv``)."""
    from rrls._io import atomic_write_table
    from rrls.evaluation import evaluate_dynamic

    result = evaluate_dynamic(
        policy,
        adversary,
        task,
        game=game,
        uncertainty=spec.uncertainty,
        episodes=spec.dynamic_episodes,
        seed=spec.eval_seed,
        alpha=0.1 if alpha is None else float(alpha),
        paper=is_paper(spec.physics),
        **_rate_game(spec, game, policy, adversary),
    )
    atomic_write_table(out / "dynamic.csv", result.episodes)
    return {"dynamic_mean": result.mean, "dynamic_std": result.std, "dynamic_env": result.env_id}


def _rate_game(spec: Spec, game: str, policy: Any, adversary: Any) -> dict[str, Any]:
    """The benchmark's rate-limited game for ``evaluate_dynamic``: TC-RMDP's (or rrls's earlier
    target game), the protagonist's view and the adversary's omniscience as their files say."""
    from rrls.evaluation.stack import policy_view

    if game != "adversarial" or spec.rate_limit is None:
        return {"rate_limit": None}
    view = policy_view(policy)
    meta = getattr(adversary, "metadata", None) or {}
    return {
        "rate_limit": spec.rate_limit,
        "rate_game": spec.rate_game,
        "observe": "vanilla" if view is None else view.observe,
        "history": 1 if view is None else view.history,
        "omniscient": bool(meta.get("omniscient", True)),
    }


def _install(root: Path, staging: Path, final: Path, result: dict[str, Any]) -> None:
    """Move the evaluated ``staging`` directory to ``final`` (replacing a previous submission
    only once the new one is complete); ``result.json`` goes in last, as for trained runs."""
    from rrls.experiments.store import write_result

    (staging / "eval" / ".lock").unlink(missing_ok=True)
    final.parent.mkdir(parents=True, exist_ok=True)
    trash = None
    if final.exists():
        trash = root / "submissions" / ".replaced" / f"{final.name}-{time.time_ns()}"
        trash.parent.mkdir(parents=True, exist_ok=True)
        final.rename(trash)
    staging.rename(final)
    write_result(final, result)
    if trash is not None:
        shutil.rmtree(trash, ignore_errors=True)
