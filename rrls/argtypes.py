"""``argparse`` value types of the ``rrls`` command line: each refuses bad text with a one-line
message naming the value (``argparse.ArgumentTypeError``), before any work starts."""

from __future__ import annotations

import argparse

#: the paper's tasks, for help texts; any registered task is accepted (``rrls.tasks.get_task``)
TASK_CHOICES = ["ant", "halfcheetah", "hopper", "humanoidstandup", "invertedpendulum", "walker"]
SET_CHOICES = ["1d", "2d", "3d", "rarl", "nominal"]


def _integer(text: str) -> int:
    try:
        return int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not an integer") from None


def positive_int(text: str) -> int:
    """argparse ``type=``: an integer >= 1."""
    value = _integer(text)
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be an integer >= 1, got {text}")
    return value


def nonnegative_int(text: str) -> int:
    """argparse ``type=``: an integer >= 0 (seeds, optional counts)."""
    value = _integer(text)
    if value < 0:
        raise argparse.ArgumentTypeError(f"must be an integer >= 0, got {text}")
    return value


def worker_count(text: str) -> int:
    """argparse ``type=``: worker processes, 0 to ``MAX_WORKERS`` (0: in this process)."""
    from rrls.evaluation.protocol import MAX_WORKERS

    value = nonnegative_int(text)
    if value > MAX_WORKERS:
        raise argparse.ArgumentTypeError(f"must be at most {MAX_WORKERS}, got {text}")
    return value


def workers_help(default: str, what: str = "") -> str:
    """``--workers``' help, the same words in every command (only the default differs): a
    user who learnt it in one command reads it right in all of them."""
    from rrls.evaluation.protocol import MAX_WORKERS

    doing = f" {what}" if what else ""
    return (
        f"N worker processes{doing}, at most {MAX_WORKERS}; 0: none, the work runs in this "
        f"process (default: {default}; results do not depend on it)"
    )


#: ``--episode-seed``'s help in every command that plays episodes (evaluate, evaluate-dynamic,
#: check); ``--seed``/``--seeds`` always name training seeds
EPISODE_SEED_HELP = (
    "root of the episodes' seeds (default 0); results depend only on it (not a training seed, "
    "which is `rrls train --seed`)"
)


#: the most steps any count may say (1e12: ~30 000 years of one env at 1 000 steps/s)
MAX_STEPS = 10**12
#: suffixes a step count may carry: 100k, 1.5M, 2g
_SCALE = {"k": 1_000, "m": 1_000_000, "g": 1_000_000_000}


def step_count(text: str) -> int:
    """argparse ``type=``: a whole number of steps from 0 to ``MAX_STEPS``, written as 30000,
    30_000, 1e4, 100k or 1.5M (a count that is not whole, such as 1.5 or 0.0005k, is refused)."""
    raw = str(text).strip().lower().replace("_", "")
    scale = _SCALE.get(raw[-1:], 1)
    number = raw[:-1] if scale != 1 else raw
    try:
        value = float(number) * scale
    except ValueError:
        value = float("nan")
    if not (0 <= value <= MAX_STEPS and value == int(value)):  # NaN fails both
        raise argparse.ArgumentTypeError(
            f"must be a whole number of steps from 0 to {MAX_STEPS:.0e} (e.g. 30000, 1e4, "
            f"100k), got {text}"
        )
    return int(value)


def seed_value(text: str) -> int:
    """argparse ``type=``: one seed, an integer from 0 to 2**32 - 1 (the one wording of
    ``rrls.seeds.seed_message`` in every command)."""
    from rrls.seeds import MAX_SEED, seed_message

    try:
        value = int(str(text).strip())
    except ValueError:
        value = -1
    if not 0 <= value <= MAX_SEED:
        shown = text if len(str(text)) <= 24 else f"{str(text)[:10]}... ({len(str(text))} digits)"
        raise argparse.ArgumentTypeError(seed_message(shown))
    return value


def positive_float(text: str) -> float:
    """argparse ``type=``: a finite float > 0 (learning rates, scales)."""
    import math

    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not math.isfinite(value) or value <= 0:
        raise argparse.ArgumentTypeError(f"must be a finite number > 0, got {text}")
    return value


def recheck_value(text: str) -> dict[str, float]:
    """argparse ``type=``: ``KxE`` or ``KxE@Q`` (``rrls.evaluation.Recheck``'s worst, episodes
    and quantile) as its JSON form."""
    import re

    match = re.fullmatch(r"\s*(\d+)\s*x\s*(\d+)\s*(?:@\s*([0-9.]+))?\s*", text)
    if match is None:
        raise argparse.ArgumentTypeError(
            f"invalid value {text!r}: write KxE or KxE@Q (10x20: the 10 lowest points, 20 fresh "
            "episodes each; @0.05: the quantile reported beside)"
        )
    from rrls.evaluation.recheck_settings import Recheck

    k, e, q = int(match[1]), int(match[2]), float(match[3]) if match[3] else 0.05
    try:
        return Recheck(k, e, q).to_json()
    except ValueError as err:
        raise argparse.ArgumentTypeError(str(err)) from None


def task_key(text: str) -> str:
    """argparse ``type=``: a task name or alias (``walker2d``), as its key."""
    from rrls.tasks import get_task

    try:
        return get_task(text).key
    except ValueError as err:
        raise argparse.ArgumentTypeError(str(err)) from None


def set_name(text: str) -> str:
    """argparse ``type=``: the name of a set some registered task declares (or ``nominal``);
    whether the chosen task has it is checked once the task is known."""
    from rrls.tasks import TASKS

    name = text.lower()
    valid = list(dict.fromkeys([*SET_CHOICES, *(s for t in TASKS.values() for s in t.sets)]))
    if name not in valid:
        choices = ", ".join(valid)
        raise argparse.ArgumentTypeError(f"invalid choice: {text!r} (choose from {choices})")
    return name


__all__ = [
    "EPISODE_SEED_HELP",
    "recheck_value",
    "SET_CHOICES",
    "TASK_CHOICES",
    "nonnegative_int",
    "positive_float",
    "positive_int",
    "set_name",
    "task_key",
    "workers_help",
]
