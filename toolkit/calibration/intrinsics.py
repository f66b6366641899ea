"""Intrinsics of one camera from views of a calibration board.

:func:`calibrate_intrinsics` runs OpenCV's ``calibrateCamera`` (pinhole, distortion
``k1, k2, p1, p2, k3``; ``k3`` fixed to 0 and the tangential terms kept unless there
are many views), rejects bad views one at a time with a reason (a view whose RMS
reprojection error is far above the others': a wrong detection, motion blur, a
rolling shutter) and reports the image coverage: the fraction of a grid of image
cells that board corners reach.  A board seen only in the middle of the image leaves
the distortion unconstrained at the borders, which is a warning.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import cv2
import numpy as np

from toolkit.calibration.boards import Board, BoardDetection
from toolkit.cameras import Camera
from toolkit.errors import InputError
from toolkit.observe import as_observer

__all__ = ["IntrinsicsConfig", "IntrinsicsResult", "calibrate_intrinsics", "coverage"]


@dataclass(frozen=True)
class IntrinsicsConfig:
    """Settings of :func:`calibrate_intrinsics`.

    Attributes
    ----------
    reject_factor : float
        A view is rejected when its RMS error exceeds ``reject_factor`` times the median view RMS
        and ``reject_min_px``.
    reject_min_px : float
        Views under this RMS (pixels) are never rejected.
    min_views : int
        Fewest views kept (rejection stops there; fewer views found is an error).
    coverage_grid : int
        Image cells per side for the coverage measure.
    min_coverage : float
        Warn when the corners reach fewer than this fraction of the cells.
    k3_min_views : int
        ``k3`` (the sixth-order radial term) is estimated only from this many views.
    """

    reject_factor: float = 3.0
    reject_min_px: float = 1.0
    min_views: int = 3
    coverage_grid: int = 4
    min_coverage: float = 0.5
    k3_min_views: int = 15


@dataclass(frozen=True, eq=False)
class IntrinsicsResult:
    """Intrinsics of one camera and how well they are supported.

    Attributes
    ----------
    camera : Camera
        K, distortion and size (identity pose).
    rms_px : float
        RMS reprojection error over the kept views, pixels.
    view_rms_px : dict of str to float
        Per kept view, its RMS reprojection error.
    rejected : list of (str, str)
        Views not used, with the reason (no board found, error too large, ...).
    coverage : float
        Fraction of the image cells (``coverage_grid`` squared) holding a corner of a kept view.
    board_poses : dict of str to ndarray of shape (4, 4)
        Per kept view, ``cam_from_board``.
    warnings : list of str
    """

    camera: Camera
    rms_px: float
    view_rms_px: dict
    rejected: list
    coverage: float
    board_poses: dict
    warnings: list = field(default_factory=list)


def coverage(points: np.ndarray, size: tuple[int, int], grid: int = 4) -> float:
    """Fraction of a ``grid x grid`` partition of the image holding at least one point.

    Parameters
    ----------
    points : ndarray of shape (N, 2)
        Pixels.
    size : tuple of int
        ``(width, height)``.
    grid : int

    Returns
    -------
    float
        In [0, 1].
    """
    p = np.asarray(points, float).reshape(-1, 2)
    w, h = size
    ix = np.clip((p[:, 0] / w * grid).astype(int), 0, grid - 1)
    iy = np.clip((p[:, 1] / h * grid).astype(int), 0, grid - 1)
    return len(set(zip(ix.tolist(), iy.tolist()))) / grid ** 2


def _calibrate(obj, img, size, n_views, cfg, K0=None):
    flags = 0 if n_views >= cfg.k3_min_views else cv2.CALIB_FIX_K3
    if K0 is not None:
        flags |= cv2.CALIB_USE_INTRINSIC_GUESS
    rms, K, dist, rvecs, tvecs = cv2.calibrateCamera(
        [o.astype(np.float32) for o in obj], [i.astype(np.float32) for i in img], size,
        None if K0 is None else K0.copy(), None, flags=flags,
        criteria=(cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-12))
    errs = []
    for o, i, r, t in zip(obj, img, rvecs, tvecs):
        uv, _ = cv2.projectPoints(o, r, t, K, dist)
        errs.append(float(np.sqrt(np.mean(np.sum((uv.reshape(-1, 2) - i) ** 2, 1)))))
    return K, dist.ravel(), rvecs, tvecs, np.array(errs)


def calibrate_intrinsics(detections: list[BoardDetection], board: Board, name: str = "camera",
                         config: IntrinsicsConfig | None = None, missed=(), observer=None) -> IntrinsicsResult:
    """Intrinsics from board detections of one camera.

    Parameters
    ----------
    detections : list of BoardDetection
        All from images of the same size.
    board : Board
    name : str
        Camera name.
    config : IntrinsicsConfig, optional
    missed : sequence of (str, str)
        Views where the board was not found, with the reason (kept in ``rejected``).
    observer : Observer, optional
        Gets ``text`` reports (warnings) and a ``series`` of per-view RMS errors.

    Returns
    -------
    IntrinsicsResult

    Raises
    ------
    InputError
        Fewer than ``min_views`` views, or images of different sizes.
    """
    cfg = config or IntrinsicsConfig()
    obs = as_observer(observer)
    sizes = {d.size for d in detections}
    if len(sizes) > 1:
        raise InputError(f"camera {name}: images", "images of one size", f"sizes {sorted(sizes)}")
    if len(detections) < cfg.min_views:
        raise InputError(f"camera {name}: board views", f"at least {cfg.min_views} images showing the board",
                         f"{len(detections)} ({len(missed)} without a board)")
    size = detections[0].size
    O = board.object_points()
    views = [d for d in detections if len(d.ids) >= 6]
    rejected = [(s, r) for s, r in missed] + [(d.source, f"only {len(d.ids)} corners") for d in detections
                                              if len(d.ids) < 6]
    while True:
        obj = [O[d.ids] for d in views]
        img = [d.corners for d in views]
        K, dist, rvecs, tvecs, errs = _calibrate(obj, img, size, len(views), cfg)
        limit = max(cfg.reject_factor * float(np.median(errs)), cfg.reject_min_px)
        worst = int(np.argmax(errs))
        if errs[worst] <= limit or len(views) <= cfg.min_views:
            break
        rejected.append((views[worst].source, f"RMS error {errs[worst]:.2f} px > {limit:.2f} px "
                                              f"({cfg.reject_factor:g} x the median view)"))
        views.pop(worst)
    rms = float(np.sqrt(np.mean(np.concatenate([
        np.sum((cv2.projectPoints(o, r, t, K, dist)[0].reshape(-1, 2) - i) ** 2, 1)
        for o, i, r, t in zip(obj, img, rvecs, tvecs)]))))
    cov = coverage(np.concatenate(img), size, cfg.coverage_grid)
    warnings = []
    if cov < cfg.min_coverage:
        warnings.append(f"camera {name}: the board reaches only {cov:.0%} of the image ({cfg.coverage_grid}x"
                        f"{cfg.coverage_grid} cells); distortion near the borders is extrapolated: add views with "
                        "the board near the edges and corners")
    if len(views) < 5:
        warnings.append(f"camera {name}: only {len(views)} usable views; 10 or more at varied tilts are advised")
    fx, fy = K[0, 0], K[1, 1]
    if abs(fx / fy - 1) > 0.05:
        warnings.append(f"camera {name}: fx / fy = {fx / fy:.3f}; square pixels give 1: check --corners "
                        "(rows and columns) and --square-mm")
    poses = {}
    for d, r, t in zip(views, rvecs, tvecs):
        T = np.eye(4)
        T[:3, :3] = cv2.Rodrigues(r)[0]
        T[:3, 3] = t.ravel()
        poses[d.source] = T
    cam = Camera(name, K, dist, size, np.eye(4))
    obs.report("series", name=f"calibration/intrinsics/{name}/view_rms_px", values=errs)
    for w in warnings:
        obs.report("text", name=f"calibration/intrinsics/{name}", text=w, level="WARN")
    return IntrinsicsResult(cam, rms, {d.source: float(e) for d, e in zip(views, errs)}, rejected, cov, poses,
                            warnings)
