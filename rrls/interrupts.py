"""What a command says when Ctrl-C stops it: one line with what was kept and the exact command
that goes on from there (``rrls.cli.main`` prints it and exits 130)."""

from __future__ import annotations

__all__ = ["KEPT", "interrupted"]


#: what each command keeps when interrupted, and how the same command goes on
KEPT = {
    "train": "checkpoints up to the last --checkpoint-every are kept",
    "evaluate": "finished mesh points are kept in the output directory",
    "evaluate-dynamic": "nothing is written until the evaluation ends",
    "submit": "nothing was submitted",
    "report": "nothing half-written (the report is written file by file, atomically)",
}


def interrupted(command: str, argv: list[str]) -> str:
    """The one line ``rrls COMMAND`` prints on Ctrl-C: what was kept, and the exact command
    that goes on from there (``train`` adds ``--resume``)."""
    import shlex

    again = ["rrls", *argv]
    if command == "train":  # --overwrite would start over: the same run, resumed
        again = [a for a in again if a != "--overwrite"]
        if "--resume" not in again:
            again.append("--resume")
    kept = KEPT.get(command, "nothing half-written")
    return f"rrls {command}: interrupted; {kept}; to go on: {shlex.join(again)}"
