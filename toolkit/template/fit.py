"""The exact 3D template fit of source 000 §2.2 (claim 8).

Each joint of an approximate 3D pose is moved to where the ray from the camera
centre through its 2D position meets the plane parallel to the image plane
through the approximate joint: the camera-frame depth of every joint is kept
and its image position becomes exact.  Bone lengths change on purpose (the
template then adapts to the subject's dimensions).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from toolkit.cameras import Camera
from toolkit.errors import InputError
from toolkit.observe import as_observer
from toolkit.skeleton import SKELETON_14
from toolkit.template.database import ApproximatePose, PoseDatabase, approximate_pose


@lru_cache(maxsize=4)
def default_database(height: float = 1.75) -> PoseDatabase:
    """The motion-library pose database for a stature (metres), built once per process."""
    return PoseDatabase.from_motion_library(height)


def exact_fit(approx_joints3d: np.ndarray, joints2d: np.ndarray, camera: Camera) -> np.ndarray:
    """Move each joint onto its 2D position, keeping its camera-frame depth.

    Parameters
    ----------
    approx_joints3d : ndarray of shape (J, 3)
        Approximate pose, world, metres; every joint with a finite 2D position
        must be finite and in front of the camera.
    joints2d : ndarray of shape (J, 2)
        Target pixels in ``camera`` (offsets already applied); NaN = keep the
        approximate joint.
    camera : Camera

    Returns
    -------
    ndarray of shape (J, 3)
        World, metres; ``camera.project`` of the result equals ``joints2d``
        wherever it is finite.

    Raises
    ------
    InputError
        Shapes differ, or a joint to move is missing or behind the camera.
    """
    X = np.asarray(approx_joints3d, float)
    x = np.asarray(joints2d, float)
    if X.ndim != 2 or X.shape[1] != 3:
        raise InputError("exact_fit: approx_joints3d", "an array of shape (J, 3)", f"shape {X.shape}")
    if x.shape != (X.shape[0], 2):
        raise InputError("exact_fit: joints2d", f"an array of shape ({X.shape[0]}, 2)", f"shape {x.shape}")
    move = np.isfinite(x).all(1)
    z = camera.depth_of(X)
    bad = move & ~(np.isfinite(z) & (z > 0))
    if bad.any():
        raise InputError("exact_fit: approx_joints3d", "finite joints in front of the camera",
                         f"joints {np.flatnonzero(bad).tolist()} missing or behind")
    out = X.copy()
    if move.any():
        out[move] = camera.backproject(x[move], z[move])
    return out


@dataclass(frozen=True)
class TemplatePose:
    """The 3D pose a template is posed with, for one camera.

    Attributes
    ----------
    joints3d : ndarray of shape (14, 3)
        World, metres; projects onto ``joints2d`` exactly where that is finite.
    joints2d : ndarray of shape (14, 2)
        The 2D pose it was fitted to (pixels, offsets applied).
    source : str
        ``"joints3d"`` (the given 3D joints were the approximate pose),
        ``"database"`` (approximate pose from the pose database) or
        ``"silhouette"`` (no joints: a standing pose fitted to the silhouette's box).
    reprojection_px : float
        Largest reprojection error over the finite 2D joints after the fit.
    """

    joints3d: np.ndarray
    joints2d: np.ndarray
    source: str
    reprojection_px: float


def fit_template_pose(camera: Camera, joints2d: np.ndarray | None = None, joints3d: np.ndarray | None = None,
                      database: PoseDatabase | None = None, *, subject_height: float = 1.75,
                      silhouette: np.ndarray | None = None, observer=None, frame: int | None = None) -> TemplatePose:
    """Approximate then exact 3D pose of a 2D pose in one view.

    Approximate pose: the given ``joints3d`` where complete (e.g. stage 1's
    triangulated joints), otherwise the best pose of ``database`` for the
    finite 2D joints, otherwise (fewer than 3 joints) a standing pose whose
    projection fills the silhouette's bounding box.  Joints of ``joints3d``
    that are NaN are taken from the database pose.  Then :func:`exact_fit`.

    Parameters
    ----------
    camera : Camera
        Corrected by stage 1's offsets (:func:`toolkit.multiview.corrected_rig`).
    joints2d : ndarray of shape (14, 2), optional
        Pixels; default ``camera.project(joints3d)``.
    joints3d : ndarray of shape (14, 3), optional
        World, metres, NaN = missing.
    database : PoseDatabase, optional
        Needed only when ``joints3d`` is incomplete; built from the motion
        library when absent and needed.
    subject_height : float
        Stature, metres (database pose size, standing fallback).
    silhouette : ndarray of shape (H, W) bool, optional
        For the standing fallback.
    observer : Observer, optional
        Receives ``joints3d`` (fitted pose) and ``joints2d`` (targets) reports.

    Returns
    -------
    TemplatePose

    Raises
    ------
    InputError
        Bad shapes, or no joints and no usable silhouette.
    """
    X = None if joints3d is None else np.asarray(joints3d, float)
    if X is not None and X.shape != (14, 3):
        raise InputError("fit_template_pose: joints3d", "an array of shape (14, 3)", f"shape {X.shape}")
    if joints2d is None:
        x = camera.project(X) if X is not None else np.full((14, 2), np.nan)
    else:
        x = np.asarray(joints2d, float)
        if x.shape != (14, 2):
            raise InputError("fit_template_pose: joints2d", "an array of shape (14, 2)", f"shape {x.shape}")
    finite3 = np.zeros(14, bool) if X is None else np.isfinite(X).all(1) & (camera.depth_of(np.nan_to_num(X)) > 0)
    if finite3.all():
        approx, source = X, "joints3d"
    elif np.isfinite(x).all(1).sum() >= 3:
        db = database if database is not None else default_database(round(float(subject_height), 2))
        ap: ApproximatePose = approximate_pose(x, camera, db, subject_height=subject_height, observer=observer,
                                               frame=frame)
        approx = ap.joints3d.copy()
        if finite3.any():  # keep the given joints, rescaled in depth to agree with the database pose
            approx[finite3] = X[finite3]
        source = "database"
    else:
        approx, x = standing_pose_in_box(camera, silhouette, subject_height), np.full((14, 2), np.nan)
        source = "silhouette"
    fitted = exact_fit(approx, x, camera)
    ok = np.isfinite(x).all(1)
    err = float(np.max(np.linalg.norm(camera.project(fitted[ok]) - x[ok], axis=1))) if ok.any() else 0.0
    obs = as_observer(observer)
    extra = {} if frame is None else {"frame": frame}
    obs.report("joints3d", joints=fitted, name=f"template/{camera.name}/fitted", skeleton=SKELETON_14, **extra)
    obs.report("joints2d", camera=camera.name, joints=x, name="template/targets", skeleton=SKELETON_14, **extra)
    return TemplatePose(fitted, x, source, err)


def standing_pose_in_box(camera: Camera, silhouette: np.ndarray | None, subject_height: float = 1.75) -> np.ndarray:
    """A standing rest pose facing the camera whose projection spans the silhouette's box.

    Parameters
    ----------
    camera : Camera
    silhouette : ndarray of shape (H, W) bool
    subject_height : float
        Metres.

    Returns
    -------
    ndarray of shape (14, 3)
        World, metres.
    """
    from toolkit.anthropometry.proportions import BodyProportions

    if silhouette is None:
        raise InputError("fit_template_pose: silhouette", "a silhouette when no joints are given", "None")
    m = np.asarray(silhouette).astype(bool)
    if m.shape != (camera.height, camera.width):
        raise InputError("fit_template_pose: silhouette", f"shape {(camera.height, camera.width)}",
                         f"shape {m.shape}")
    ys, xs = np.nonzero(m)
    if len(ys) == 0:
        raise InputError("fit_template_pose: silhouette", "a non-empty silhouette when no joints are given",
                         "an empty mask")
    top, bottom = ys.min(), ys.max()
    cx = 0.5 * (xs.min() + xs.max())
    rest = BodyProportions.from_height(subject_height).rest_pose()
    # the person stands on the ray through the box's bottom centre, facing the camera
    o, d = camera.rays(np.array([[cx, 0.5 * (top + bottom)]]))
    z_mid = 0.5 * subject_height
    s = (z_mid - o[0, 2]) / d[0, 2] if abs(d[0, 2]) > 1e-6 else 10.0
    if not s > 0:
        s = 10.0
    centre = o[0] + s * d[0]
    fwd = camera.center - centre
    fwd[2] = 0.0
    yaw = np.arctan2(fwd[1], fwd[0]) - np.pi / 2  # rest pose faces +y
    c, sn = np.cos(yaw), np.sin(yaw)
    R = np.array([[c, -sn, 0], [sn, c, 0], [0, 0, 1.0]])
    pel = rest[[_LH, _RH]].mean(0)
    pose = (rest - [pel[0], pel[1], 0.0]) @ R.T + [centre[0], centre[1], 0.0]
    # scale about the pose's mid-height point so that the projected height matches the box
    proj = camera.project(pose)
    ph = np.nanmax(proj[:, 1]) - np.nanmin(proj[:, 1])
    k = (bottom - top) / ph * 1.0 if ph > 1 else 1.0
    mid = pose.mean(0)
    zc = camera.depth_of(mid)
    return camera.backproject(camera.project(mid[None]), np.array([zc]))[0] + (pose - mid) * k


_LH, _RH = SKELETON_14.joint_names.index("l_hip"), SKELETON_14.joint_names.index("r_hip")
