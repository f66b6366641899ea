"""Anthropometry: body proportions and anthropometric constraints."""

from toolkit.anthropometry.proportions import STATURE_RANGE_M, STATURE_RATIOS, BodyProportions

__all__ = ["STATURE_RANGE_M", "STATURE_RATIOS", "BodyProportions"]
