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
#: the paper's column headings where they differ from the registered class-name stem
PAPER_TASK_NAMES = {"humanoidstandup": "HumanoidStandup", "walker": "Walker"}


def task_name(task: str) -> str:
    """A task's display name: the paper's heading for its tasks, else the class-name stem it
    was registered with (``rrls.register_task(name=...)``), else the key itself."""
    if task in PAPER_TASK_NAMES:
        return PAPER_TASK_NAMES[task]
    from rrls.tasks import TASKS

    spec = TASKS.get(task)
    return spec.name if spec is not None else task


def sort_algos(algos: Iterable[str]) -> list[str]:
    """The paper's order first, then the others alphabetically (duplicates dropped)."""
    algos = list(dict.fromkeys(algos))
    return sorted(algos, key=lambda a: (ORDER.index(a) if a in ORDER else len(ORDER), a))
