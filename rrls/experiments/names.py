"""How algorithms and tasks are named and ordered in tables and figures (report and plots both
read this; neither imports the other for it)."""

from __future__ import annotations

from collections.abc import Iterable

ORDER = ("td3", "dr", "m2td3", "rarl", "nrmdp", "sac", "sacdr")  # the paper's rows, then SAC's
NAMES = {
    "td3": "TD3",
    "dr": "DR",
    "m2td3": "M2TD3",
    "rarl": "RARL",
    "nrmdp": "NR-MDP",
    "sac": "SAC",
    "sacdr": "SAC-DR",
}
TASK_NAMES = {
    "ant": "Ant",
    "halfcheetah": "HalfCheetah",
    "hopper": "Hopper",
    "humanoidstandup": "HumanoidStandup",
    "invertedpendulum": "InvertedPendulum",
    "walker": "Walker",
}


def sort_algos(algos: Iterable[str]) -> list[str]:
    """The paper's order first, then the others alphabetically (duplicates dropped)."""
    algos = list(dict.fromkeys(algos))
    return sorted(algos, key=lambda a: (ORDER.index(a) if a in ORDER else len(ORDER), a))
