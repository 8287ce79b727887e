"""Robust evaluation: meshes over uncertainty sets (the runner comes with the evaluation issue)."""

from rrls.evaluation.mesh import (
    EvaluationSet,
    default_evaluation_set,
    evaluation_points,
    generate_evaluation_set,
    resolve_uncertainty,
)

__all__ = [
    "EvaluationSet",
    "default_evaluation_set",
    "evaluation_points",
    "generate_evaluation_set",
    "resolve_uncertainty",
]
