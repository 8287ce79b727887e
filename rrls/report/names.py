"""How algorithms and tasks are named and ordered in tables and figures (report and plots both
read this; neither imports the other for it)."""

from __future__ import annotations

from rrls.algorithms import ALGORITHMS, display_name, normalisers, sort_algos

#: the built-in algorithms in the paper's row order, then SAC's (``rrls.algorithms``: the table)
ORDER = tuple(sort_algos(ALGORITHMS))
#: display names are read from the table at use (``display_name``): a plug-in registered after
#: this module was imported is named by its row too
__all__ = [
    "ORDER",
    "PAPER_TASK_NAMES",
    "display_name",
    "normaliser_names",
    "sort_algos",
    "task_name",
]
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


def normaliser_names() -> tuple[str, str]:
    """The display names of the normalised score's 0 and 1 anchors (``normalisers``: TD3,
    M2TD3), as every caption, note and heading that names them writes them."""
    zero, one = (display_name(a) for a in normalisers())
    return zero, one
