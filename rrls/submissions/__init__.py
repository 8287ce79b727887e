"""Submissions: a policy trained anywhere, entered into a benchmark (``rrls submit``).

``steps`` — :func:`submit` in its three steps, each callable alone: check
(:func:`check_submission`: the name, the benchmark, the policy's shapes, all before any
episode), evaluate (:func:`evaluate_submission`: the benchmark's own protocol, in a staging
folder), install (:func:`install_submission`: one all-or-nothing change of the results);
``checks`` — the check step whole (``check_submission``, the benchmark submitted to among
its checks);
``withdraw`` — ``rrls withdraw``: a submission taken out again.

Built on :mod:`rrls.benchmark` (a submission is a run of a benchmark); the report reads it
like any run.
"""

from __future__ import annotations

from rrls.lazy import lazy_exports

_WHERE = {
    **dict.fromkeys(
        [
            "Submission",
            "SubmitError",
            "create_benchmark",
            "evaluate_submission",
            "install_submission",
            "submit",
        ],
        "steps",
    ),
    "check_submission": "checks",
    "remove_submission": "withdraw",
}

__getattr__, __dir__ = lazy_exports(__name__, _WHERE, globals())

__all__ = sorted(_WHERE)
