"""Sparse bundle adjustment of camera poses with 3D points or rigid board poses.

Intrinsics stay fixed (they come from :mod:`toolkit.calibration.intrinsics`): the
observations are undistorted once to normalised image coordinates and the residuals
are normalised errors times the camera's focal length, i.e. about pixels.  The
solver is ``scipy.optimize.least_squares`` (trust-region reflective, LSMR steps) with
an analytic sparse Jacobian (each residual depends on one camera and one point or
board pose; rotation derivatives of Gallego and Yezzi, 2015) and a robust loss (``soft_l1`` by default), so that wrong detections
(a keypoint on the wrong leg) do not pull the solution.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from scipy.optimize import least_squares

from toolkit.cameras import Camera

__all__ = ["Observations", "BundleResult", "bundle_adjust", "rodrigues", "pose_params", "pose_from_params"]


def rodrigues(r: np.ndarray) -> np.ndarray:
    """Rotation matrices (N, 3, 3) of Rodrigues vectors (N, 3) (vectorised)."""
    r = np.asarray(r, float).reshape(-1, 3)
    th = np.linalg.norm(r, axis=1)
    k = np.where(th[:, None] > 1e-12, r / np.maximum(th, 1e-300)[:, None], 0.0)
    K = np.zeros((len(r), 3, 3))
    K[:, 0, 1], K[:, 0, 2], K[:, 1, 2] = -k[:, 2], k[:, 1], -k[:, 0]
    K[:, 1, 0], K[:, 2, 0], K[:, 2, 1] = k[:, 2], -k[:, 1], k[:, 0]
    s, c = np.sin(th)[:, None, None], np.cos(th)[:, None, None]
    return np.eye(3)[None] + s * K + (1 - c) * (K @ K)


def _skew(u: np.ndarray) -> np.ndarray:
    """Cross-product matrices (N, 3, 3) of vectors (N, 3)."""
    S = np.zeros(u.shape[:-1] + (3, 3))
    S[..., 0, 1], S[..., 0, 2], S[..., 1, 2] = -u[..., 2], u[..., 1], -u[..., 0]
    S[..., 1, 0], S[..., 2, 0], S[..., 2, 1] = u[..., 2], -u[..., 1], u[..., 0]
    return S


def rotation_jacobian_factor(r: np.ndarray) -> np.ndarray:
    """Per Rodrigues vector ``v`` the (3, 3) factor ``A`` of d(R u)/dv = -R [u]x A (Gallego and Yezzi, 2015).

    ``A = (v v^T + (R^T - I)[v]x) / |v|^2``, and the identity for ``v`` near zero.
    """
    r = np.asarray(r, float).reshape(-1, 3)
    R = rodrigues(r)
    n2 = np.sum(r ** 2, 1)
    A = np.broadcast_to(np.eye(3), (len(r), 3, 3)).copy()
    big = n2 > 1e-16
    if big.any():
        v = r[big]
        A[big] = (v[:, :, None] * v[:, None, :]
                  + (np.transpose(R[big], (0, 2, 1)) - np.eye(3)) @ _skew(v)) / n2[big, None, None]
    return A


def pose_params(T: np.ndarray) -> np.ndarray:
    """(6,) Rodrigues vector and translation of a 4x4 rigid transform."""
    return np.concatenate([cv2.Rodrigues(np.asarray(T[:3, :3], float))[0].ravel(), T[:3, 3]])


def pose_from_params(p: np.ndarray) -> np.ndarray:
    """4x4 rigid transform of (6,) parameters (:func:`pose_params`)."""
    T = np.eye(4)
    T[:3, :3] = cv2.Rodrigues(np.asarray(p[:3], float).reshape(3, 1))[0]
    T[:3, 3] = p[3:6]
    return T


@dataclass(frozen=True, eq=False)
class Observations:
    """2D observations of 3D points.

    Attributes
    ----------
    cam : ndarray of shape (M,) of int
        Camera index of each observation.
    point : ndarray of shape (M,) of int
        Point index (free points) or board-pose index (rigid boards).
    corner : ndarray of shape (M,) of int or None
        Rigid boards: the board corner (row of the object points).
    xy : ndarray of shape (M, 2)
        Undistorted normalised image coordinates.
    """

    cam: np.ndarray
    point: np.ndarray
    xy: np.ndarray
    corner: np.ndarray | None = None

    @classmethod
    def from_pixels(cls, cameras: list[Camera], cam, point, uv, corner=None) -> "Observations":
        cam, point = np.asarray(cam, int), np.asarray(point, int)
        uv = np.asarray(uv, float).reshape(-1, 2)
        xy = np.zeros_like(uv)
        for c in np.unique(cam):
            m = cam == c
            xy[m] = cameras[c].undistort_points(uv[m])
        return cls(cam, point, xy, None if corner is None else np.asarray(corner, int))


@dataclass(frozen=True, eq=False)
class BundleResult:
    """Refined poses and points.

    Attributes
    ----------
    cam_from_world : ndarray of shape (C, 4, 4)
    points : ndarray of shape (N, 3)
        Free points (metres), or the board poses' translations for rigid boards.
    board_poses : ndarray of shape (B, 4, 4) or None
        Rigid boards: ``world_from_board`` per board pose.
    residuals_px : ndarray of shape (M,)
        Reprojection error of every observation, pixels (normalised error times fx).
    cost : float
    """

    cam_from_world: np.ndarray
    points: np.ndarray
    board_poses: np.ndarray | None
    residuals_px: np.ndarray
    cost: float


def _project(cam_p: np.ndarray, X: np.ndarray, obs: Observations) -> np.ndarray:
    R = rodrigues(cam_p[:, :3])
    Xc = np.einsum("mij,mj->mi", R[obs.cam], X) + cam_p[obs.cam, 3:6]
    z = np.where(np.abs(Xc[:, 2]) < 1e-9, 1e-9, Xc[:, 2])
    return Xc[:, :2] / z[:, None]


def _world_points(pp: np.ndarray, obs: Observations, Bp: np.ndarray | None) -> np.ndarray:
    """The world point of every observation.

    Parameters
    ----------
    pp : ndarray of shape (N, 3) or (B, 6)
        Free points (metres), or board poses as Rodrigues vector and translation.
    obs : Observations
    Bp : ndarray of shape (P, 3) or None
        Board corners in board coordinates, metres (None for free points).

    Returns
    -------
    ndarray of shape (M, 3)
        Metres, world frame.
    """
    if Bp is None:
        return pp[obs.point]
    R = rodrigues(pp[:, :3])
    return np.einsum("mij,mj->mi", R[obs.point], Bp[obs.corner]) + pp[obs.point, 3:6]


def _sparse_jacobian(cp: np.ndarray, pp: np.ndarray, obs: Observations, f: np.ndarray, Bp: np.ndarray | None,
                     cam_col: np.ndarray, n_c: int, n_cols: int):
    """Analytic Jacobian (sparse, 2M x n): projection chain rule with exact Rodrigues derivatives.

    Parameters
    ----------
    cp : ndarray of shape (C, 6)
        Camera poses (Rodrigues vector, translation).
    pp : ndarray of shape (N, 3) or (B, 6)
        Free points or board poses.
    obs : Observations
        M observations.
    f : ndarray of shape (M,)
        Focal length of each observation's camera, pixels.
    Bp : ndarray of shape (P, 3) or None
        Board corners (None for free points).
    cam_col : ndarray of int, shape (M,)
        First column of each observation's camera parameters (-1 for a fixed camera).
    n_c : int
        Number of camera parameter columns.
    n_cols : int
        Number of columns.

    Returns
    -------
    scipy.sparse.csr_matrix of shape (2 M, n_cols)
        Pixels per parameter unit.
    """
    rigid = Bp is not None
    M = len(obs.cam)
    rows2 = np.arange(2 * M).reshape(M, 2)
    Rc = rodrigues(cp[:, :3])
    Xw = _world_points(pp, obs, Bp)
    Xc = np.einsum("mij,mj->mi", Rc[obs.cam], Xw) + cp[obs.cam, 3:6]
    z = np.where(np.abs(Xc[:, 2]) < 1e-9, 1e-9, Xc[:, 2])
    P = np.zeros((M, 2, 3))
    P[:, 0, 0] = P[:, 1, 1] = f / z
    P[:, 0, 2] = -f * Xc[:, 0] / z ** 2
    P[:, 1, 2] = -f * Xc[:, 1] / z ** 2
    PR = P @ Rc[obs.cam]  # d residual / d world point, (M, 2, 3)
    blocks_r, blocks_c, blocks_v = [], [], []

    def add(block, col0, m_idx):
        k = block.shape[-1]
        blocks_r.append(np.repeat(rows2[m_idx], k, axis=1).ravel())
        blocks_c.append((col0[:, None, None] + np.arange(k)[None, None, :]).repeat(2, 1).ravel())
        blocks_v.append(block.ravel())

    mc = cam_col >= 0
    if mc.any():
        A = rotation_jacobian_factor(cp[:, :3])
        # d Xc / d v = -R [Xw]x A
        dR = -np.einsum("mij,mjk,mkl->mil", Rc[obs.cam[mc]], _skew(Xw[mc]), A[obs.cam[mc]])
        add(np.concatenate([P[mc] @ dR, P[mc]], axis=2), cam_col[mc], np.flatnonzero(mc))
    all_m = np.arange(M)
    if rigid:
        Rb = rodrigues(pp[:, :3])
        Ab = rotation_jacobian_factor(pp[:, :3])
        dRb = -np.einsum("mij,mjk,mkl->mil", Rb[obs.point], _skew(Bp[obs.corner]), Ab[obs.point])
        add(np.concatenate([PR @ dRb, PR], axis=2), n_c + 6 * obs.point, all_m)
    else:
        add(PR, n_c + 3 * obs.point, all_m)
    from scipy.sparse import csr_matrix

    return csr_matrix((np.concatenate(blocks_v), (np.concatenate(blocks_r), np.concatenate(blocks_c))),
                      shape=(2 * M, n_cols))


def bundle_adjust(cameras: list[Camera], obs: Observations, points: np.ndarray | None = None,
                  board_poses: np.ndarray | None = None, board_points: np.ndarray | None = None,
                  fixed_cameras=(0,), loss: str = "soft_l1", f_scale_px: float = 2.0, max_nfev: int = 200,
                  x_scale="jac", ftol: float = 1e-8) -> BundleResult:
    """Refine camera poses with free 3D points or with rigid board poses.

    Parameters
    ----------
    cameras : list of Camera
        Initial poses; K and distortion are kept.
    obs : Observations
    points : ndarray of shape (N, 3), optional
        Initial free points (metres); exclusive with ``board_poses``.
    board_poses : ndarray of shape (B, 4, 4), optional
        Initial ``world_from_board`` per board pose.
    board_points : ndarray of shape (P, 3), optional
        Board corners in board coordinates (with ``board_poses``).
    fixed_cameras : sequence of int
        Cameras whose poses are not changed (the gauge: at least one for free points).
    loss : str
        ``least_squares`` loss (``linear``, ``huber``, ``soft_l1``, ``cauchy``).
    f_scale_px : float
        Residual (pixels) where the robust loss starts to flatten.
    max_nfev : int
    x_scale : str or ndarray
        ``least_squares``' parameter scaling.
    ftol : float
        Stop when an iteration lowers the cost by less than this fraction.

    Returns
    -------
    BundleResult
    """
    C = len(cameras)
    f = np.array([c.K[0, 0] for c in cameras])[obs.cam]
    free = [c for c in range(C) if c not in set(fixed_cameras)]
    cam_p0 = np.array([pose_params(c.cam_from_world) for c in cameras])
    rigid = board_poses is not None
    if rigid:
        P0 = np.array([pose_params(T) for T in board_poses])
        n_pp = 6
        Bp = np.asarray(board_points, float)
    else:
        P0 = np.asarray(points, float).reshape(-1, 3)
        n_pp = 3
        Bp = None
    n_c = 6 * len(free)
    slot = {c: i for i, c in enumerate(free)}

    def unpack(x):
        cp = cam_p0.copy()
        if free:
            cp[free] = x[:n_c].reshape(-1, 6)
        return cp, x[n_c:].reshape(-1, n_pp)

    def fun(x):
        cp, pp = unpack(x)
        return ((_project(cp, _world_points(pp, obs, Bp), obs) - obs.xy) * f[:, None]).ravel()

    cam_col = np.array([6 * slot[c] if c in slot else -1 for c in range(C)])[obs.cam]

    def jac(x):
        cp, pp = unpack(x)
        return _sparse_jacobian(cp, pp, obs, f, Bp, cam_col, n_c, n_c + n_pp * len(P0))

    x0 = np.concatenate([cam_p0[free].ravel(), P0.ravel()])
    res = least_squares(fun, x0, jac=jac, loss=loss, f_scale=f_scale_px, method="trf", x_scale=x_scale,
                        max_nfev=max_nfev, xtol=1e-10, ftol=ftol, tr_solver="lsmr")
    cp, pp = unpack(res.x)
    Ts = np.array([pose_from_params(p) for p in cp])
    r = res.fun.reshape(-1, 2)
    if rigid:
        bp = np.array([pose_from_params(p) for p in pp])
        return BundleResult(Ts, bp[:, :3, 3], bp, np.linalg.norm(r, axis=1), float(res.cost))
    return BundleResult(Ts, pp, None, np.linalg.norm(r, axis=1), float(res.cost))
