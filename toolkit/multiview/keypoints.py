"""Detector keypoints (x, y, confidence) as multi-view candidates.

A 2D detector gives one pose per view with a confidence per joint.  Joints
below a confidence threshold are missing; a view whose detected joints are on
average below a second threshold is dropped for that frame (a detection of
the wrong person, or of nobody, is usually weak everywhere).
"""

from __future__ import annotations

import numpy as np

from toolkit.errors import InputError

#: Joints with a detector confidence below this are treated as missing.  Pose2Sim's
#: demo configuration uses 0.3 as its likelihood threshold for triangulation.
MIN_JOINT_CONFIDENCE = 0.3
#: A view whose mean confidence over its detected joints is below this is dropped.
MIN_VIEW_CONFIDENCE = 0.3


def keypoints_to_candidates(keypoints: np.ndarray, min_joint_confidence: float = MIN_JOINT_CONFIDENCE,
                            min_view_confidence: float = MIN_VIEW_CONFIDENCE):
    """One candidate per view, confidence-weighted, from (x, y, c) joints.

    Parameters
    ----------
    keypoints : ndarray of shape (n_views, n_joints, 3)
        Pixels and confidence in [0, 1]; NaN or c = 0 for undetected joints.
    min_joint_confidence : float
    min_view_confidence : float

    Returns
    -------
    candidates : ndarray of shape (n_views, 1, n_joints, 2)
        Pixels; NaN for missing joints and dropped views.
    weights : ndarray of shape (n_views, 1, n_joints)
        The confidences of the kept joints, 0 elsewhere.
    """
    k = np.asarray(keypoints, float)
    if k.ndim != 3 or k.shape[2] != 3:
        raise InputError("keypoints", "an array of shape (n_views, n_joints, 3) (x, y, confidence)",
                         f"shape {k.shape}")
    xy, c = k[..., :2], np.nan_to_num(k[..., 2])
    keep = np.isfinite(xy).all(-1) & (c >= min_joint_confidence) & (c > 0)
    with np.errstate(invalid="ignore"):
        view_conf = np.where(keep.any(-1), np.sum(np.where(keep, c, 0), -1) / np.maximum(keep.sum(-1), 1), 0.0)
    keep &= (view_conf >= min_view_confidence)[:, None]
    cand = np.where(keep[..., None], xy, np.nan)[:, None]
    w = np.where(keep, c, 0.0)[:, None]
    return cand, w
