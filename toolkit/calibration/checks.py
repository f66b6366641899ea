"""Checks a user can trust: what a calibration's reprojection error does not show.

A mirrored board pose or a world frame whose up axis points into the floor fits the
images as well as the right one (FreeMoCap #862); these checks look at the geometry
instead: cameras must be above the floor, a board must be seen from its printed side,
a person's left must be on their left, scene coordinates must be right-handed, and the
scale must be pinned by something.
"""

from __future__ import annotations

import numpy as np

from toolkit.cameras import Rig
from toolkit.io.keypoint_files import normalise_name

__all__ = ["UNDER_FLOOR_MARGIN_M", "MIRRORED_FRACTION", "cameras_under_floor", "person_chirality",
           "mirrored_person_warning", "boards_seen_from_behind", "reprojection_summary"]

#: A camera centre this far below the floor (z = 0) is "under the floor", metres.
UNDER_FLOOR_MARGIN_M = 0.05
#: A person is reported mirrored when this fraction of the frames has their left on their right.
MIRRORED_FRACTION = 0.5


def cameras_under_floor(rig: Rig, margin: float = UNDER_FLOOR_MARGIN_M) -> list[str]:
    """Warnings for cameras whose centre is below the floor ``z = 0`` (world z up).

    Parameters
    ----------
    rig : Rig
    margin : float
        Metres below the floor tolerated.

    Returns
    -------
    list of str
        Empty when every camera is above the floor.
    """
    low = [(c.name, float(c.center[2])) for c in rig if c.center[2] < -margin]
    if not low:
        return []
    where = ", ".join(f"{n} at z = {z:.2f} m" for n, z in low)
    return [f"cameras under the floor ({where}): the world's up axis points down (a mirrored board pose or a "
            "floor fitted upside down) although the reprojection error may look perfect"]


def person_chirality(points: dict[str, np.ndarray]) -> np.ndarray:
    """Per frame, +1 when the person's left is on their left, -1 when mirrored, NaN when unknown.

    Names are compared without case, punctuation or spelling of sides (``LShoulder`` is ``left_shoulder``,
    :func:`toolkit.io.keypoint_files.normalise_name`).  The body's up is mid-shoulders minus mid-hips, its left the right-to-left shoulder vector, and its front
    the direction from the ears' midpoint to the nose (or heels to big toes).  For a real person
    ``left . (up x front) > 0`` (z up, facing +y: left is -x).

    Parameters
    ----------
    points : dict of str to ndarray of shape (T, 3)
        3D keypoints by name: ``l_shoulder``, ``r_shoulder``, ``l_hip``, ``r_hip`` and either
        ``nose`` with ``l_ear`` / ``r_ear``, or ``l_big_toe`` / ``r_big_toe`` with ``l_heel`` / ``r_heel``.

    Returns
    -------
    ndarray of shape (T,)
    """
    g = {normalise_name(k): np.asarray(v, float) for k, v in points.items()}
    T = len(next(iter(g.values())))
    if not all(k in g for k in ("lshoulder", "rshoulder", "lhip", "rhip")):
        return np.full(T, np.nan)
    left = g["lshoulder"] - g["rshoulder"]
    up = 0.5 * (g["lshoulder"] + g["rshoulder"]) - 0.5 * (g["lhip"] + g["rhip"])
    if all(k in g for k in ("nose", "lear", "rear")):
        front = g["nose"] - 0.5 * (g["lear"] + g["rear"])
    elif all(k in g for k in ("lbigtoe", "rbigtoe", "lheel", "rheel")):
        front = 0.5 * (g["lbigtoe"] + g["rbigtoe"] - g["lheel"] - g["rheel"])
    else:
        return np.full(T, np.nan)
    s = np.einsum("ti,ti->t", left, np.cross(up, front))
    return np.where(np.isfinite(s), np.sign(s), np.nan)


def mirrored_person_warning(points: dict[str, np.ndarray], fraction: float = MIRRORED_FRACTION) -> list[str]:
    """A warning when the reconstructed person is mirrored in most frames (see :func:`person_chirality`)."""
    s = person_chirality(points)
    s = s[np.isfinite(s)]
    if len(s) == 0 or np.mean(s < 0) <= fraction:
        return []
    return [f"mirrored solution: in {np.mean(s < 0):.0%} of {len(s)} frames the person's left side is on their "
            "right (a mirrored camera image, a world frame with one axis flipped, or every view's left/right "
            "labels swapped)"]


def boards_seen_from_behind(cam_from_board: dict, margin: float = 0.0) -> list[str]:
    """Warnings for board poses whose camera is on the board's back side (a mirrored pose).

    Parameters
    ----------
    cam_from_board : dict of (str, str) to ndarray of shape (4, 4)
        Per (camera, view) the board's pose in the camera.
    margin : float
        Metres behind the board's plane tolerated.

    Returns
    -------
    list of str
    """
    bad = []
    for (cam, view), T in cam_from_board.items():
        centre_in_board = -T[:3, :3].T @ T[:3, 3]  # camera centre in board coordinates
        if centre_in_board[2] > margin:
            bad.append(f"{cam}/{view}")
    if not bad:
        return []
    return [f"board seen from behind in {', '.join(bad)}: a mirrored (flipped) board pose; the printed side faces "
            "the camera in any real view, so these detections or their corner order are wrong"]


def reprojection_summary(names: list[str], cam_index: np.ndarray, residuals_px: np.ndarray) -> dict:
    """Per camera: observations, median, RMS and 95th percentile of the reprojection errors (pixels)."""
    out = {}
    for c, n in enumerate(names):
        r = residuals_px[cam_index == c]
        if len(r):
            out[n] = {"n": int(len(r)), "median_px": float(np.median(r)),
                      "rms_px": float(np.sqrt(np.mean(r ** 2))), "p95_px": float(np.percentile(r, 95))}
        else:
            out[n] = {"n": 0, "median_px": float("nan"), "rms_px": float("nan"), "p95_px": float("nan")}
    return out
