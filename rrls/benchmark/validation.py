"""What a benchmark may not be: every check made before any process starts (``validate``),
so that a benchmark that cannot run is refused in one line, with exit status 2, not after
hours of training. Apart from ``grid`` (what a benchmark is) because the checks read most of the
library (tasks, sets, splits, the twin's table) and change for other reasons."""

from __future__ import annotations

from typing import Any

from rrls.algorithms import ALGORITHMS, algorithm_info
from rrls.evaluation.protocol import Protocol, check_episodes
from rrls.physics import SIMULATORS, is_paper
from rrls.wrappers.tc_rmdp import OBSERVE

__all__ = ["SpecError", "check_protocol", "task_key", "validate"]


class SpecError(ValueError):
    """A benchmark specification that cannot run (the CLI prints it on one line, exit 2)."""


def task_key(task: str) -> str:
    """The registry's key of ``task`` (any spelling), or ``SpecError`` naming the valid ones."""
    from rrls.tasks import get_task

    try:
        return get_task(task).key
    except ValueError as err:
        raise SpecError(str(err)) from None


def validate(spec: Any) -> None:
    """Raise ``SpecError`` for anything that cannot run (before any process starts)."""
    from importlib.metadata import entry_points

    from rrls.envs import get_uncertainty_set
    from rrls.tasks import TASKS, get_task

    plugins = [ep.name for ep in entry_points(group="rrls.algorithms")]
    bad = [a for a in spec.algos if algorithm_info(a) is None]  # registered rows count too
    if bad:
        valid = ", ".join(dict.fromkeys([*ALGORITHMS, *plugins]))
        raise SpecError(f"unknown algorithm {bad[0]!r}; valid: {valid}, or package.module:Learner")
    if not spec.algos or not spec.tasks:
        raise SpecError("a benchmark needs at least one algorithm and one task")
    check_protocol(spec.protocol)
    for task in spec.tasks:
        key = task_key(task)
        if is_paper(spec.physics) and get_task(key).paper_id is None:
            valid = ", ".join(k for k, t in TASKS.items() if t.paper_id is not None)
            raise SpecError(
                f"task {key!r} has no paper physics; valid with --physics paper: {valid}"
            )
        for name in {spec.uncertainty, *(spec.train_set(a) for a in spec.algos)}:
            try:
                get_uncertainty_set(key, name)
            except ValueError as err:
                raise SpecError(str(err)) from None
        try:  # the final evaluation (its size, disruptors, schedule), refused now, not after
            spec.protocol.plan(key)  # the training
            box = get_uncertainty_set(key, spec.uncertainty)
            check_episodes(1, spec.dynamic_episodes)
            if spec.eval_mesh:
                check_episodes(box.mesh_size(spec.eval_mesh), spec.eval_episodes)
        except (TypeError, ValueError) as err:
            raise SpecError(f"{key}: {err}") from None
    for name in ("steps", "eval_episodes"):  # the protocol's counts: checked by the Protocol
        if getattr(spec, name) < 1:
            raise SpecError(f"--{name.replace('_', '-')} must be >= 1, got {getattr(spec, name)}")
    for name in ("learning_starts", "eval_every", "eval_mesh"):
        if (getattr(spec, name) or 0) < 0:
            raise SpecError(f"--{name.replace('_', '-')} must be >= 0, got {getattr(spec, name)}")
    if not spec.seeds or min(spec.seeds) < 0:
        raise SpecError("--seeds must be >= 1")
    if spec.checkpoint_every < 1:
        raise SpecError("checkpoint_every must be >= 1")
    if spec.split:
        from rrls.envs import training_split

        for task in spec.tasks:
            try:
                training_split(task_key(task), spec.uncertainty, spec.split)
            except ValueError as err:
                raise SpecError(str(err)) from None
    if spec.rate_limit is not None:  # (a finite number > 0: the Protocol checks it)
        movers = [a.name for a in ALGORITHMS.values() if a.set_use == "adversary"]
        if not set(movers) & set(spec.algos):
            raise SpecError(
                "--rate-limit applies to an adversary moving the parameters: add "
                f"{' or '.join(movers)} to --algos"
            )
    from rrls.wrappers.tc_rmdp import RATE_GAMES

    if spec.rate_game not in RATE_GAMES:
        raise SpecError(f"rate_game must be one of {', '.join(RATE_GAMES)}, got {spec.rate_game!r}")
    if spec.observe not in OBSERVE:
        raise SpecError(f"--observe must be one of {', '.join(OBSERVE)}, got {spec.observe!r}")
    if spec.simulator not in SIMULATORS:
        raise SpecError(f"--simulator must be {' or '.join(SIMULATORS)}, got {spec.simulator!r}")
    if spec.simulator == "warp":  # the tasks without a twin train on CPU MuJoCo beside them
        from rrls.twin.catalog import check_twin

        keys = [task_key(task) for task in spec.tasks]
        on_twin = [t for t in keys if spec.simulator_for(t) == "warp"] or keys[:1]
        for algo in spec.algos:
            for task in on_twin:
                try:
                    check_twin(algo, task, spec.physics)
                except ValueError as err:
                    raise SpecError(str(err)) from None
    if spec.observe != "vanilla" and (spec.rate_limit is None or spec.rate_game != "tc"):
        raise SpecError(
            f"--observe {spec.observe} is a protagonist of TC-RMDP's game: add --rate-limit R"
        )


def check_protocol(protocol: Protocol) -> None:
    """Refuse a protocol a benchmark cannot train for: its set and split must be named (every
    run trains on them), and no ``context`` (rrls's training shows its policies no context:
    they would be evaluated on observations they never saw)."""
    if not isinstance(protocol.uncertainty, str):
        raise SpecError(
            "a benchmark's protocol names its uncertainty set (1d, 2d, 3d...: every run trains "
            "on it), not an UncertaintySet"
        )
    if protocol.split is not None and not isinstance(protocol.split, str):
        raise SpecError("a benchmark's protocol gives its split as text (extrapolation:0.5)")
    if protocol.context:
        raise SpecError(
            "context=true: a benchmark's runs train without the set's parameters in their "
            "observations, so they cannot be evaluated with them; evaluate a context-aware "
            "policy with rrls.evaluation.evaluate(..., context=True)"
        )
