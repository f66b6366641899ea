"""Anthropometry: body proportions and anthropometric constraints."""

from toolkit.anthropometry.constraints import (
    GROUND_MARGIN_M,
    REASONS,
    SYMMETRIC_TOLERANCE,
    AnthropometricConstraints,
    Violation,
    reason_names,
)
from toolkit.anthropometry.limits import (
    ANKLE_CLEARANCE_M,
    ANSUR_II_PERCENTILES,
    LANDMARK_WIDENING_FRACTION,
    LANDMARK_WIDENING_MIN_M,
    LIMITS_14,
    Limit,
    SurveyPercentiles,
    derive_limits_from_ansur,
    limits_markdown,
)
from toolkit.anthropometry.proportions import STATURE_RANGE_M, STATURE_RATIOS, BodyProportions

__all__ = [
    "ANKLE_CLEARANCE_M",
    "ANSUR_II_PERCENTILES",
    "GROUND_MARGIN_M",
    "LANDMARK_WIDENING_FRACTION",
    "LANDMARK_WIDENING_MIN_M",
    "LIMITS_14",
    "REASONS",
    "STATURE_RANGE_M",
    "STATURE_RATIOS",
    "SYMMETRIC_TOLERANCE",
    "AnthropometricConstraints",
    "BodyProportions",
    "Limit",
    "SurveyPercentiles",
    "Violation",
    "derive_limits_from_ansur",
    "limits_markdown",
    "reason_names",
]
