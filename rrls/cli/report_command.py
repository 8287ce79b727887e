"""``rrls report``: rebuild a benchmark's result store and write its report (the library's
:func:`rrls.report.writer.make_report`). Named ``report_command`` because
:mod:`rrls.report.writer` is the report itself."""

from __future__ import annotations

import argparse
import shlex
from typing import Any

from rrls.cli.benchmark_options import guarded, results_table
from rrls.cli.parsing import fail
from rrls.report.reference import SHIPPED

NAME = "report"


def add_parser(sub: argparse._SubParsersAction) -> argparse.ArgumentParser:
    """Register ``rrls report`` on the ``rrls`` sub-command parser."""
    r = sub.add_parser(
        NAME,
        help="regenerate a benchmark's report (summary.json, report.md, tables, figures)",
        description="Rebuild DIR/results from the run directories and write DIR/report: "
        "summary.json, report.md, tables/*.tex (booktabs) and *.csv, figures. Several DIRs "
        "with --out OUT: one report across their tasks in OUT/report.",
    )
    r.add_argument(
        "dir",
        nargs="+",
        help="a `rrls benchmark --out` directory; several (with --out): one report across "
        "their tasks, each task from one of them (the paper's Tables 4-5 over references "
        "trained a task at a time)",
    )
    r.add_argument(
        "--out",
        metavar="DIR",
        help="with several benchmark directories: where the joined report is written (DIR/report)",
    )
    r.add_argument("--no-plots", action="store_true", help="skip the figures")
    r.add_argument(
        "--no-titles",
        action="store_true",
        help="figures without titles (for a paper, whose captions say what each shows)",
    )
    r.add_argument(
        "--reference",
        metavar="FILE",
        help=f"reference results (.json/.csv, or a shipped name: {', '.join(SHIPPED)}) normalising"
        " the tasks without their own TD3 and M2TD3 runs; refused if measured under another"
        " protocol (physics, set, mesh, episodes) or with another training budget (see"
        " --allow-other-budget)",
    )
    r.add_argument(
        "--export-reference",
        metavar="FILE",
        help="also write this benchmark's results (every algorithm, per-seed values) as a "
        "reference file (.json, or .csv) another lab can pass to --reference",
    )
    r.add_argument("--label", help="--export-reference: the reference's label")
    r.add_argument(
        "--notes",
        help="--export-reference: what a reader must know of its runs (budget, what differs, "
        "where they ran); default: the directory it was exported from",
    )
    r.add_argument(
        "--rename",
        action="append",
        metavar="NAME=TEXT",
        help="show algorithm NAME's row as TEXT in every table and figure (NAME@REF: the "
        "reference REF's row, e.g. td3@quick='TD3, rrls quick'); repeatable",
    )
    r.add_argument(
        "--cells",
        choices=("ci", "pm"),
        default="ci",
        help="what each cell of tables/*.tex shows: ci, mean [95%% CI] (default), or pm, "
        "mean ± std (the paper's style); bold by overlapping 95%% intervals either way",
    )
    r.add_argument(
        "--allow-other-budget",
        action="store_true",
        help="accept a --reference trained with another budget (steps) than this benchmark's: "
        "its rows are marked ‡, normalised by its own TD3 and M2TD3 and never bold",
    )
    return r


def run(args: argparse.Namespace) -> int:
    """Write the report and print its table; a bad input is one line, exit status 2."""
    return guarded(args, _report)


def _report(args: argparse.Namespace) -> int:
    from pathlib import Path

    from rrls.benchmark.benchfile import reporting, stored_fingerprints
    from rrls.benchmark.store import build_store
    from rrls.interrupts import identity, keeping
    from rrls.report.exported import export_reference
    from rrls.report.reference import ReferenceError
    from rrls.report.writer import make_report

    roots = [Path(d) for d in args.dir]
    for root in roots:
        if not (root / "runs").is_dir() and not (root / "results").is_dir():
            return fail("report", f"{root} is not a benchmark directory (no runs/ or results/)")
    labels = {}
    for item in args.rename or []:
        name, sep, text = item.partition("=")
        if not sep or not name.strip() or not text.strip():
            return fail(
                "report", f"--rename {item!r}: write NAME=TEXT (NAME@REF for a reference row)"
            )
        labels[name.strip()] = text.strip()
    if len(roots) > 1 or args.out:
        return _joined(args, roots, labels)
    root = roots[0]
    written = [root / name for name in FOLDERS]
    if args.export_reference:
        written.append(Path(args.export_reference))
    before = {path: identity(path) for path in written}
    with keeping(lambda: _rebuilt(root, before)):
        try:
            with reporting(root):  # one store and report at a time (a benchmark ending, too)
                if (root / "runs").is_dir():
                    build_store(root, stored_fingerprints(root))
                path = make_report(
                    root,
                    plots=not args.no_plots,
                    reference=args.reference,
                    labels=labels or None,
                    titles=not args.no_titles,
                    cells=args.cells,
                    allow_other_budget=args.allow_other_budget,
                )
                exported = None
                if args.export_reference:
                    exported = export_reference(
                        root, args.export_reference, label=args.label, notes=args.notes
                    )
        except ReferenceError as err:
            return fail("report", str(err))
        print(results_table(root))
        print(f"report: {path}")
        if exported is not None:
            print(
                f"reference: {args.export_reference} ({exported.label!r}: "
                f"{len(exported.rows)} cells; `rrls report DIR --reference "
                f"{shlex.quote(str(args.export_reference))}`)"
            )
    return 0


def _joined(args: argparse.Namespace, roots: list[Any], labels: dict[str, str]) -> int:
    """``rrls report DIR DIR ... --out OUT``: each benchmark's store rebuilt under its own lock,
    then one report across their tasks in OUT/report."""
    from pathlib import Path

    from rrls.benchmark.benchfile import reporting, stored_fingerprints
    from rrls.benchmark.store import build_store
    from rrls.interrupts import identity, keeping
    from rrls.report.writer import make_cross_report

    if len(roots) < 2 or not args.out:
        return fail("report", "a joined report takes two or more DIRs and --out OUT")
    for flag, given in (
        ("--reference", args.reference),
        ("--export-reference", args.export_reference),
        ("--allow-other-budget", args.allow_other_budget),
    ):
        if given:
            return fail(
                "report",
                f"{flag} applies to one benchmark; a joined report normalises each "
                "task by its own benchmark's TD3 and M2TD3",
            )
    out = Path(args.out)
    before = {out / "report": identity(out / "report")}
    with keeping(lambda: _rebuilt(out, before)):
        for root in roots:
            if (root / "runs").is_dir():
                with reporting(root):
                    build_store(root, stored_fingerprints(root))
        try:
            path = make_cross_report(
                roots,
                out,
                plots=not args.no_plots,
                labels=labels or None,
                titles=not args.no_titles,
                cells=args.cells,
            )
        except ValueError as err:
            return fail("report", str(err))
    print(f"report: {path}")
    return 0


#: the folders ``rrls report`` rebuilds, each replaced whole or not at all
FOLDERS = ("results", "report")


def _rebuilt(root: Any, before: dict[Any, tuple[int, int] | None]) -> str:
    """What an interrupted ``rrls report`` left: the folders (and exported reference) it had
    replaced; the others are as they were, whole (each is swapped in only once complete)."""
    from rrls.interrupts import identity

    now = {path: identity(path) for path in before}
    new = [str(p) for p in before if now[p] is not None and now[p] != before[p]]
    old = [str(p) for p in before if now[p] is not None and now[p] == before[p]]
    parts = [f"{' and '.join(new)} rewritten"] if new else []
    if old:
        parts.append(f"{' and '.join(old)} as before, whole")
    return "; ".join(parts) or f"no report in {root} yet"


__all__ = ["NAME", "add_parser", "run"]
