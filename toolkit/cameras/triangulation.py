"""Multi-view triangulation.

Shapes follow ``(n_cams, ..., 2)`` for observations and ``(..., 3)`` for
points, in pixels and metres; NaN marks a missing observation.
"""

from __future__ import annotations

import numpy as np

from toolkit.cameras.camera import Camera, Rig
from toolkit.errors import InputError


def _check_obs(rig: Rig | list[Camera], points2d: np.ndarray) -> np.ndarray:
    pts = np.asarray(points2d, dtype=np.float64)
    if pts.ndim < 2 or pts.shape[0] != len(rig) or pts.shape[-1] != 2:
        raise InputError("points2d", f"an array of shape ({len(rig)}, ..., 2) (one slice per camera)",
                         f"shape {pts.shape}")
    return pts


def triangulate_linear(rig: Rig | list[Camera], points2d: np.ndarray, min_views: int = 2) -> np.ndarray:
    """Direct linear transform triangulation (on undistorted points).

    Parameters
    ----------
    rig : Rig or list of Camera
    points2d : ndarray of shape (n_cams, ..., 2)
        Pixels; NaN where a camera did not see the point.
    min_views : int
        Points seen by fewer cameras come back NaN.

    Returns
    -------
    ndarray of shape (..., 3)
    """
    pts = _check_obs(rig, points2d)
    shape = pts.shape[1:-1]
    n_cams = len(rig)
    norm = np.stack([c.undistort_points(pts[i]) for i, c in enumerate(rig)]).reshape(n_cams, -1, 2)
    P = np.stack([c.cam_from_world[:3, :] for c in rig])  # normalised coordinates
    out = np.full((norm.shape[1], 3), np.nan)
    for j in range(norm.shape[1]):
        ok = np.isfinite(norm[:, j]).all(axis=1)
        if ok.sum() < min_views:
            continue
        rows = []
        for i in np.flatnonzero(ok):
            x, y = norm[i, j]
            rows.append(x * P[i, 2] - P[i, 0])
            rows.append(y * P[i, 2] - P[i, 1])
        A = np.array(rows)
        _, _, vt = np.linalg.svd(A)
        X = vt[-1]
        if abs(X[3]) > 1e-12:
            out[j] = X[:3] / X[3]
    return out.reshape(*shape, 3)


def closest_point_to_rays(origins: np.ndarray, directions: np.ndarray,
                          weights: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Least-squares point closest to a bundle of rays, batched.

    Parameters
    ----------
    origins : ndarray of shape (R, ..., 3)
        Ray origins for R rays per point.
    directions : ndarray of shape (R, ..., 3)
        Ray directions (normalised internally); NaN rays are ignored.
    weights : ndarray of shape (R, ...), optional
        Non-negative ray weights.

    Returns
    -------
    points : ndarray of shape (..., 3)
        NaN where fewer than two non-parallel rays are available.
    distances : ndarray of shape (R, ...)
        Distance from each ray to the point (NaN for ignored rays).
    """
    o = np.asarray(origins, float)
    d = np.asarray(directions, float)
    if o.shape != d.shape or o.shape[-1] != 3:
        raise InputError("closest_point_to_rays", "origins and directions of equal shape (R, ..., 3)",
                         f"{o.shape} and {d.shape}")
    d = d / np.linalg.norm(d, axis=-1, keepdims=True)
    valid = np.isfinite(o).all(-1) & np.isfinite(d).all(-1)
    w = np.ones(o.shape[:-1]) if weights is None else np.asarray(weights, float)
    w = np.where(valid, w, 0.0)
    o0 = np.where(valid[..., None], o, 0.0)
    d0 = np.where(valid[..., None], d, 0.0)
    # sum_i w_i (I - d_i d_i^T) X = sum_i w_i (I - d_i d_i^T) o_i
    M = np.eye(3) - d0[..., :, None] * d0[..., None, :]
    A = np.sum(w[..., None, None] * M, axis=0)
    b = np.sum(w[..., None, None] * M @ o0[..., None], axis=0)[..., 0]
    det = np.linalg.det(A)
    good = (valid.sum(axis=0) >= 2) & (np.abs(det) > 1e-12)
    X = np.full(A.shape[:-1], np.nan)
    if good.any():
        X[good] = np.linalg.solve(A[good], b[good][..., None])[..., 0]
    diff = X[None] - o
    along = np.sum(diff * d, axis=-1, keepdims=True)
    dist = np.linalg.norm(diff - along * d, axis=-1)
    dist = np.where(valid, dist, np.nan)
    return X, dist


def triangulate_rays(rig: Rig | list[Camera], points2d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Triangulate as the point closest to the back-projected rays.

    Parameters
    ----------
    rig : Rig or list of Camera
    points2d : ndarray of shape (n_cams, ..., 2)
        Pixels, NaN for missing views.

    Returns
    -------
    points : ndarray of shape (..., 3)
        NaN where fewer than two cameras saw the point.
    distances : ndarray of shape (n_cams, ...)
        Ray-to-point distances in metres (NaN for missing views).
    """
    pts = _check_obs(rig, points2d)
    o, d = zip(*(c.rays(pts[i]) for i, c in enumerate(rig)))
    return closest_point_to_rays(np.stack(o), np.stack(d))


def reprojection_errors(rig: Rig | list[Camera], points3d: np.ndarray, points2d: np.ndarray) -> np.ndarray:
    """Pixel distance between projected 3D points (..., 3) and observations (n_cams, ..., 2)."""
    pts = _check_obs(rig, points2d)
    proj = np.stack([c.project(points3d) for c in rig])
    return np.linalg.norm(proj - pts, axis=-1)
