"""How to install an optional extra, said once for every message that needs one.

rrls installs from a clone of its repository (it is not on a package index), so the line that
works is pip on the checkout with the project's constraints file (which keeps pip on the CPU
build of torch): ``python3 -m pip install -c constraints.txt ".[train]"`` run in the checkout.
"""

from __future__ import annotations

__all__ = ["install_hint"]


def install_hint(extra: str) -> str:
    """The command that installs ``extra`` (e.g. ``train``, ``sb3,eval``), for an error message."""
    return f"""in the rrls checkout: python3 -m pip install -c constraints.txt ".[{extra}]\""""
