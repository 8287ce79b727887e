"""Robust evaluation (paper §4-5): meshes, the batched rollout engine, scores, worst-case search."""

from rrls.evaluation.dynamic import (
    DynamicResult,
    evaluate_dynamic,
    evaluate_run_dynamic,
    make_dynamic_env,
)
from rrls.evaluation.lanes import PolicyError
from rrls.evaluation.mesh import (
    EvaluationSet,
    default_evaluation_set,
    evaluation_points,
    generate_evaluation_set,
    resolve_uncertainty,
)
from rrls.evaluation.metrics import normalized_score
from rrls.evaluation.policies import (
    BatchInvariant,
    MLPPolicy,
    SB3Policy,
    TorchPolicy,
    as_policy,
    load_policy,
)
from rrls.evaluation.prepared import PreparedPolicy, prepare
from rrls.evaluation.protocol import Protocol
from rrls.evaluation.result import EvaluationResult
from rrls.evaluation.result_plot import plot_result
from rrls.evaluation.search import WorstCaseSearch, search_worst_case
from rrls.evaluation.static import evaluate

__all__ = [
    "BatchInvariant",
    "DynamicResult",
    "WorstCaseSearch",
    "evaluate_dynamic",
    "evaluate_run_dynamic",
    "make_dynamic_env",
    "plot_result",
    "prepare",
    "search_worst_case",
    "EvaluationResult",
    "EvaluationSet",
    "MLPPolicy",
    "PolicyError",
    "PreparedPolicy",
    "Protocol",
    "SB3Policy",
    "TorchPolicy",
    "as_policy",
    "default_evaluation_set",
    "evaluate",
    "evaluation_points",
    "generate_evaluation_set",
    "load_policy",
    "normalized_score",
    "resolve_uncertainty",
]
