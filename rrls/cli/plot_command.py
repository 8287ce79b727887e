"""``rrls plot``: draw a saved evaluation (the library's
:func:`rrls.evaluation.result_plot.plot_result`); a command of its own, so its options and what
it does read in one place."""

from __future__ import annotations

import argparse

NAME = "plot"


def add_parser(sub: argparse._SubParsersAction) -> argparse.ArgumentParser:
    """Register ``rrls plot`` on the ``rrls`` sub-command parser."""
    plot = sub.add_parser(
        NAME,
        help="plot a saved evaluation: return over the uncertainty set",
        description="Draw the mean return over the uncertainty set from an `rrls evaluate` "
        "output directory: a line (1D), a heatmap (2D) or three slices through the worst point "
        "on one colour scale (3D).",
    )
    plot.add_argument("dir", help="an `rrls evaluate` output directory")
    plot.add_argument("--out", help="PNG path (default: DIR/returns.png)")
    return plot


def run(args: argparse.Namespace) -> int:
    """Draw the figure and print its path."""
    from pathlib import Path

    from rrls.evaluation.result_plot import plot_result
    from rrls.interrupts import identity, keeping

    if not Path(args.dir).is_dir():
        raise FileNotFoundError(f"no evaluation directory {args.dir}")
    path = Path(args.out or Path(args.dir) / "returns.png")
    before = identity(path)

    def kept() -> tuple[str, bool | None]:  # the figure is written whole or not at all
        now = identity(path)
        if now is not None and now != before:
            return f"{path} written", None
        return f"{path} not written" + (" (the earlier one kept)" if now else ""), False

    with keeping(kept):
        print(plot_result(args.dir, path))
    return 0


__all__ = ["NAME", "add_parser", "run"]
