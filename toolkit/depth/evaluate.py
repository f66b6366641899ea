"""Scoring depth-tracking results: errors against ground truth, plausibility without it, overlay pictures.

* :func:`errors_per_point` and :func:`summarise` give MPJPE per control point,
  over all frames, over the points the camera sees and over frames where it
  sees all 13, and the share of frames tracked.
* :func:`plausibility` checks a skeleton against a depth frame when there is
  no ground truth (the real Kinect frames): the head above the shoulders, the
  arm samples inside the user's silhouette.
* :func:`draw_skeleton` draws a skeleton over a depth frame (an RGB image for
  the documentation).
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from toolkit.pointcloud.cloud import ViewFrame
from toolkit.body.control_points import (
    HEAD,
    L_ELBOW,
    L_HAND,
    L_SHOULDER,
    N_POINTS,
    R_ELBOW,
    R_HAND,
    R_SHOULDER,
)
from toolkit.errors import InputError
from toolkit.skeleton import JOINTS_13, SKELETON_13

__all__ = [
    "ARM_SAMPLES",
    "Plausibility",
    "TrackingSummary",
    "draw_skeleton",
    "errors_per_point",
    "plausibility",
    "summarise",
]

#: Points along each arm checked against the silhouette: fractions along shoulder-elbow and elbow-hand.
ARM_SAMPLES = (0.5, 1.0, 1.5, 2.0)


def errors_per_point(joints: np.ndarray, truth: np.ndarray) -> np.ndarray:
    """Euclidean errors (T, n) of estimates (T, n, 3) against ground truth (T, n, 3), NaN where no estimate."""
    J = np.asarray(joints, float)
    G = np.asarray(truth, float)
    if J.shape != G.shape or J.ndim != 3 or J.shape[-1] != 3:
        raise InputError("joints", f"an array of the ground truth's shape {G.shape}", f"shape {J.shape}")
    return np.linalg.norm(J - G, axis=-1)


@dataclass(frozen=True)
class TrackingSummary:
    """Scores of one tracked sequence.

    Attributes
    ----------
    mpjpe_m : float
        Mean error over frames with an estimate and all points.
    mpjpe_visible_m : float
        Mean error over the points the camera sees (ground-truth visibility).
    mpjpe_unoccluded_m : float
        Mean error over frames where the camera sees all 13 points.
    per_point_m : ndarray of shape (13,)
        Mean error per control point (frames with an estimate).
    tracked_share : float
        Frames in state ``tracking``.
    estimated_share : float
        Frames with an estimate (``recovering`` or ``tracking``).
    n_frames : int
    """

    mpjpe_m: float
    mpjpe_visible_m: float
    mpjpe_unoccluded_m: float
    per_point_m: np.ndarray
    tracked_share: float
    estimated_share: float
    n_frames: int


def summarise(joints: np.ndarray, truth: np.ndarray, states: np.ndarray, visible: np.ndarray | None = None,
              tracking_state: int = 2) -> TrackingSummary:
    """Scores of a sequence (see :class:`TrackingSummary`).

    Parameters
    ----------
    joints, truth : ndarray of shape (T, 13, 3)
    states : ndarray of shape (T,), int
    visible : ndarray of shape (T, 13), bool, optional
        Ground-truth visibility (all visible when omitted).
    tracking_state : int
    """
    E = errors_per_point(joints, truth)
    st = np.asarray(states)
    est = np.all(np.isfinite(E), axis=1)
    vis = np.ones(E.shape, bool) if visible is None else np.asarray(visible, bool)
    with np.errstate(invalid="ignore"):
        all_m = float(np.nanmean(E[est])) if est.any() else float("nan")
        sel = vis & est[:, None]
        vis_m = float(np.mean(E[sel])) if sel.any() else float("nan")
        full = est & vis.all(1)
        unocc = float(np.mean(E[full])) if full.any() else float("nan")
        per = np.nanmean(np.where(est[:, None], E, np.nan), axis=0) if est.any() else np.full(E.shape[1], np.nan)
    return TrackingSummary(all_m, vis_m, unocc, per, float(np.mean(st == tracking_state)), float(np.mean(est)),
                           len(st))


@dataclass(frozen=True)
class Plausibility:
    """Checks of a skeleton against its depth frame.

    Attributes
    ----------
    head_above_shoulders : bool
        The head is higher than both shoulders (gravity, or the image's up without a pose).
    arms_inside : float
        Fraction of the arm samples (:data:`ARM_SAMPLES`) inside the image that fall
        on the (slightly dilated) user mask.
    points_inside : float
        Fraction of the control points inside the image that fall on the dilated mask.
    """

    head_above_shoulders: bool
    arms_inside: float
    points_inside: float

    def ok(self, min_inside: float = 0.8) -> bool:
        return self.head_above_shoulders and self.arms_inside >= min_inside


def _arm_samples(X: np.ndarray) -> np.ndarray:
    out = []
    for s, e, h in ((L_SHOULDER, L_ELBOW, L_HAND), (R_SHOULDER, R_ELBOW, R_HAND)):
        for f in ARM_SAMPLES:
            out.append(X[s] + f * (X[e] - X[s]) if f <= 1 else X[e] + (f - 1) * (X[h] - X[e]))
    return np.array(out)


def plausibility(joints_view: np.ndarray, frame: ViewFrame, mask: np.ndarray, dilate_px: int = 4) -> Plausibility:
    """Check a view-frame skeleton (13, 3) against the user mask of its depth frame."""
    X = np.asarray(joints_view, float)
    if X.shape != (N_POINTS, 3):
        raise InputError("joints_view", f"an array of shape ({N_POINTS}, 3)", f"shape {X.shape}")
    m = cv2.dilate(np.asarray(mask, np.uint8), np.ones((2 * dilate_px + 1,) * 2, np.uint8)) > 0
    h, w = m.shape

    def inside(P):
        uv = frame.project(P)
        ok = np.all(np.isfinite(uv), axis=1) & (uv[:, 0] >= 0) & (uv[:, 0] <= w - 1) & (uv[:, 1] >= 0) & \
            (uv[:, 1] <= h - 1)
        if not ok.any():
            return 1.0
        q = np.round(uv[ok]).astype(int)
        return float(m[q[:, 1], q[:, 0]].mean())

    head_up = bool(X[HEAD, 1] < X[L_SHOULDER, 1] and X[HEAD, 1] < X[R_SHOULDER, 1])
    return Plausibility(head_up, inside(_arm_samples(X)), inside(X))


def draw_skeleton(depth: np.ndarray, uv: np.ndarray, observed: np.ndarray | None = None, text: str = "",
                  depth_range=(0.5, 4.5), scale: float = 1.0) -> np.ndarray:
    """Draw a 13-point skeleton over a depth frame.

    Parameters
    ----------
    depth : ndarray of shape (H, W)
        Metres, NaN = no reading (drawn black; nearer is brighter).
    uv : ndarray of shape (13, 2)
        Pixel positions of the control points (NaN = not drawn).
    observed : ndarray of shape (13,), bool, optional
        Observed points are green, completed ones blue.
    text : str
        A caption in the top-left corner.
    depth_range : tuple of float
        Depths mapped to white and dark grey.
    scale : float
        Output size factor (e.g. 0.5 for small documentation images).

    Returns
    -------
    ndarray of shape (H * scale, W * scale, 3), uint8 RGB
        Bones red; left-side points drawn larger than right-side ones.
    """
    d = np.asarray(depth, np.float32)
    lo, hi = depth_range
    g = np.where(np.isfinite(d), 230 - 180 * np.clip((d - lo) / (hi - lo), 0, 1), 0).astype(np.uint8)
    img = cv2.cvtColor(g, cv2.COLOR_GRAY2RGB)
    if scale != 1.0:
        img = cv2.resize(img, None, fx=scale, fy=scale, interpolation=cv2.INTER_AREA)
    P = np.asarray(uv, float) * scale
    obs = np.ones(len(P), bool) if observed is None else np.asarray(observed, bool)
    ok = np.all(np.isfinite(P), axis=1)
    pts = [tuple(int(round(v)) for v in q) if k else None for q, k in zip(P, ok)]
    th = max(1, int(round(2 * scale)))
    for a, b in SKELETON_13.edges:
        if pts[a] is not None and pts[b] is not None:
            cv2.line(img, pts[a], pts[b], (230, 40, 40), th, cv2.LINE_AA)
    for i, q in enumerate(pts):
        if q is None:
            continue
        r = max(2, int(round((5 if JOINTS_13[i].startswith("l_") else 3.5) * scale)))
        cv2.circle(img, q, r, (40, 210, 40) if obs[i] else (60, 120, 255), -1, cv2.LINE_AA)
    if text:
        cv2.putText(img, text, (4, max(12, int(16 * scale))), cv2.FONT_HERSHEY_SIMPLEX, 0.45 * max(scale, 0.8),
                    (255, 255, 0), 1, cv2.LINE_AA)
    return img
