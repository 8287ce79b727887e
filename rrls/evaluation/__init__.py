"""Robust evaluation: meshes over uncertainty sets and the paper's scores (runner: issue 3)."""

from rrls.evaluation.mesh import (
    EvaluationSet,
    default_evaluation_set,
    evaluation_points,
    generate_evaluation_set,
    resolve_uncertainty,
)
from rrls.evaluation.metrics import normalized_score

__all__ = [
    "EvaluationSet",
    "default_evaluation_set",
    "evaluation_points",
    "generate_evaluation_set",
    "normalized_score",
    "resolve_uncertainty",
]
