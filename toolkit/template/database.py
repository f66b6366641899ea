"""A database of 3D poses and the approximate 3D pose of a 2D pose (source 000 §2.2).

The source takes the approximate 3D pose from a motion-capture database
searched for a pose whose projection roughly matches the 2D joints (after
Hornung et al. [HDK07]).  Here the database holds 14-joint poses from the
procedural motion library (:mod:`toolkit.motion.library`) or from BVH files,
each stored *canonical*: pelvis (mid-hip) at the origin, hips along +x
(heading removed), metres, z up.

The search runs over every database pose, a set of root orientations (yaw
about the vertical axis, :data:`YAW_STEPS` of them) and the image scale: for
each candidate the scale and the image translation are solved in closed form
(weak perspective in normalised camera coordinates), and the candidate with
the smallest reprojection error wins.  The depth of the root follows from the
scale and the pose's size in metres (``pose_scale`` adapts that size to the
subject's stature).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from toolkit.anthropometry.proportions import BodyProportions
from toolkit.cameras import Camera
from toolkit.errors import InputError
from toolkit.observe import as_observer
from toolkit.skeleton import SKELETON_14

#: Root orientations tried by :func:`approximate_pose` (yaw steps over a full turn).
YAW_STEPS = 36
#: Frames sampled from each motion of the procedural library for the default database.
FRAMES_PER_MOTION = 40

_J = {n: i for i, n in enumerate(SKELETON_14.joint_names)}
_LHIP, _RHIP = _J["l_hip"], _J["r_hip"]


def canonical_poses(joints: np.ndarray) -> np.ndarray:
    """Remove the position and heading of poses.

    Parameters
    ----------
    joints : ndarray of shape (N, 14, 3)
        World poses, metres, z up.

    Returns
    -------
    ndarray of shape (N, 14, 3)
        Pelvis (hip mid-point) at the origin, the right-to-left hip vector along
        +x (rotation about z only), metres.
    """
    J = np.asarray(joints, float)
    if J.ndim != 3 or J.shape[1:] != (14, 3):
        raise InputError("canonical_poses: joints", "an array of shape (N, 14, 3)", f"shape {J.shape}")
    pelvis = 0.5 * (J[:, _LHIP] + J[:, _RHIP])
    P = J - pelvis[:, None]
    lat = P[:, _LHIP, :2] - P[:, _RHIP, :2]
    ang = np.arctan2(lat[:, 1], lat[:, 0])
    c, s = np.cos(-ang), np.sin(-ang)
    x = c[:, None] * P[..., 0] - s[:, None] * P[..., 1]
    y = s[:, None] * P[..., 0] + c[:, None] * P[..., 1]
    return np.stack([x, y, P[..., 2]], -1)


@dataclass(frozen=True)
class PoseDatabase:
    """Canonical 3D poses of the 14-joint skeleton.

    Attributes
    ----------
    poses : ndarray of shape (N, 14, 3)
        Canonical poses (see :func:`canonical_poses`), metres.
    height : float
        Stature (metres) of the body the poses were made for; poses are
        rescaled by ``subject_height / height`` when fitted.
    sources : tuple of str
        Where each pose came from (``"walk:12"``, ``"file.bvh:40"``), length N.
    """

    poses: np.ndarray
    height: float
    sources: tuple

    def __post_init__(self):
        P = np.asarray(self.poses, float)
        if P.ndim != 3 or P.shape[1:] != (14, 3) or len(P) == 0 or not np.isfinite(P).all():
            raise InputError("PoseDatabase.poses", "a finite array of shape (N>0, 14, 3)", f"shape {P.shape}")
        if len(self.sources) != len(P):
            raise InputError("PoseDatabase.sources", f"{len(P)} entries", f"{len(self.sources)}")
        if not self.height > 0:
            raise InputError("PoseDatabase.height", "a positive stature in metres", repr(self.height))

    def __len__(self) -> int:
        return len(self.poses)

    @classmethod
    def from_joints(cls, joints: np.ndarray, height: float, sources=None) -> "PoseDatabase":
        """A database of world poses (N, 14, 3), made canonical; NaN poses are dropped."""
        J = np.asarray(joints, float)
        if J.ndim != 3 or J.shape[1:] != (14, 3):
            raise InputError("PoseDatabase.from_joints: joints", "an array of shape (N, 14, 3)", f"shape {J.shape}")
        ok = np.isfinite(J).all(axis=(1, 2))
        src = tuple(sources) if sources is not None else tuple(f"pose:{i}" for i in range(len(J)))
        if len(src) != len(J):
            raise InputError("PoseDatabase.from_joints: sources", f"{len(J)} entries", f"{len(src)}")
        return cls(canonical_poses(J[ok]), float(height), tuple(s for s, k in zip(src, ok) if k))

    @classmethod
    def from_motion_library(cls, height: float = 1.75, motions=None, frames_per_motion: int = FRAMES_PER_MOTION,
                            rng: np.random.Generator | int | None = 0) -> "PoseDatabase":
        """Poses sampled from the procedural motion library (:data:`toolkit.motion.MOTIONS`).

        Parameters
        ----------
        height : float
            Stature of the median body the motions are generated for, metres.
        motions : sequence of str, optional
            Motion names (default: :data:`toolkit.motion.SCENE_MOTIONS`, all but the lab's ``rom`` trial).
        frames_per_motion : int
            Poses kept per motion (evenly spaced over a 3 s clip).
        rng : numpy.random.Generator or int or None
            Seeds the motion variations.
        """
        from toolkit.motion import SCENE_MOTIONS, generate_motion

        rng = np.random.default_rng(rng)
        names = tuple(SCENE_MOTIONS if motions is None else motions)
        props = BodyProportions.from_height(float(height))
        fps = 25.0
        n = 75
        J, src = [], []
        for name in names:
            m = generate_motion(name, props, n, fps, rng=rng)
            idx = np.unique(np.linspace(0, n - 1, int(frames_per_motion)).round().astype(int))
            J.append(m[idx])
            src += [f"{name}:{i}" for i in idx]
        return cls.from_joints(np.concatenate(J), height, src)

    @classmethod
    def from_bvh(cls, paths, height: float = 1.75, every: int = 5, **bvh_options) -> "PoseDatabase":
        """Poses from BVH files (every ``every``-th frame at 25 fps), mapped to the 14-joint skeleton.

        Parameters
        ----------
        paths : sequence of str or PathLike
        height : float
            Stature the poses are retargeted to (bone lengths of the median body), metres.
        every : int
            Keep every ``every``-th frame.
        **bvh_options
            ``mapping``, ``units``, ``up_axis`` of :func:`toolkit.motion.motion_from_bvh`
            (default: the CMU motion-capture library's).
        """
        from toolkit.motion import motion_from_bvh

        J, src = [], []
        for p in paths:
            joints = motion_from_bvh(p, BodyProportions.from_height(float(height)), **bvh_options)
            idx = np.arange(0, len(joints), max(1, int(every)))
            J.append(joints[idx])
            src += [f"{Path(p).name}:{i}" for i in idx]
        if not J:
            raise InputError("PoseDatabase.from_bvh: paths", "at least one BVH file", "none")
        return cls.from_joints(np.concatenate(J), height, src)


@dataclass(frozen=True)
class ApproximatePose:
    """The database pose that best explains a 2D pose.

    Attributes
    ----------
    joints3d : ndarray of shape (14, 3)
        World, metres (the database pose rotated, scaled and placed).
    error_px : float
        RMS reprojection error over the given 2D joints, pixels.
    index : int
        Database pose index.
    yaw : float
        Root orientation about z, radians.
    depth : float
        Camera-frame depth of the pelvis, metres.
    success : bool
        False when fewer than 3 joints were given or every candidate failed.
    """

    joints3d: np.ndarray
    error_px: float
    index: int
    yaw: float
    depth: float
    success: bool

    def __bool__(self) -> bool:
        return bool(self.success)


def _weak_perspective_fit(q: np.ndarray, n: np.ndarray, w: np.ndarray):
    """Per candidate, scale k and translation t minimising sum w |k q + t - n|^2.

    q : (M, J, 2) rotated pose in camera axes (x, y); n : (J, 2) targets; w : (J,) 0/1.
    Returns k (M,), t (M, 2), residual sum of squares (M,).
    """
    sw = w.sum()
    qm = (w[None, :, None] * q).sum(1) / sw
    nm = (w[:, None] * n).sum(0) / sw
    qc = q - qm[:, None]
    nc = n - nm
    num = (w[None, :, None] * qc * nc[None]).sum((1, 2))
    den = (w[None, :, None] * qc * qc).sum((1, 2))
    k = num / np.maximum(den, 1e-12)
    t = nm[None] - k[:, None] * qm
    r = k[:, None, None] * q + t[:, None] - n[None]
    return k, t, (w[None, :, None] * r * r).sum((1, 2))


def approximate_pose(joints2d: np.ndarray, camera: Camera, database: PoseDatabase, *,
                     subject_height: float | None = None, yaw_steps: int = YAW_STEPS,
                     observer=None, frame: int | None = None) -> ApproximatePose:
    """Approximate 3D pose of a 2D pose: database search over pose, root yaw and scale.

    Parameters
    ----------
    joints2d : ndarray of shape (14, 2)
        Pixels in ``camera`` (offsets already applied), NaN = missing.
    camera : Camera
    database : PoseDatabase
    subject_height : float, optional
        Stature of the subject (metres); sets the pose size and therefore the
        depth.  Default: the database's.
    yaw_steps : int
        Root orientations tried over a full turn.
    observer : Observer, optional
        Receives a ``text`` report (chosen pose, yaw, error) and the pose as ``joints3d``.

    Returns
    -------
    ApproximatePose
        Falsy (``success=False``, NaN joints) with fewer than 3 finite joints.
    """
    x = np.asarray(joints2d, float)
    if x.shape != (14, 2):
        raise InputError("approximate_pose: joints2d", "an array of shape (14, 2)", f"shape {x.shape}")
    if yaw_steps < 1:
        raise InputError("approximate_pose: yaw_steps", "a positive count", repr(yaw_steps))
    ok = np.isfinite(x).all(1)
    if ok.sum() < 3:
        return ApproximatePose(np.full((14, 3), np.nan), float("inf"), -1, float("nan"), float("nan"), False)
    h = float(subject_height) if subject_height is not None else database.height
    scale = h / database.height
    n = np.zeros((14, 2))
    n[ok] = camera.undistort_points(x[ok])
    w = ok.astype(float)
    yaws = np.arange(yaw_steps) * (2 * np.pi / yaw_steps)
    c, s = np.cos(yaws), np.sin(yaws)
    Rz = np.zeros((yaw_steps, 3, 3))
    Rz[:, 0, 0], Rz[:, 0, 1], Rz[:, 1, 0], Rz[:, 1, 1], Rz[:, 2, 2] = c, -s, s, c, 1.0
    P = database.poses * scale  # (N, 14, 3)
    # camera-frame coordinates of each rotated pose (about its pelvis): R Rz P
    M = np.einsum("ij,yjk->yik", camera.R, Rz)  # (Y, 3, 3)
    q = np.einsum("yik,njk->ynji", M, P)  # (Y, N, 14, 3)
    Y, N = q.shape[:2]
    k, t, rss = _weak_perspective_fit(q[..., :2].reshape(Y * N, 14, 2), n, w)
    rss = np.where(k > 0, rss, np.inf)
    best = int(np.argmin(rss))
    if not np.isfinite(rss[best]):
        return ApproximatePose(np.full((14, 3), np.nan), float("inf"), -1, float("nan"), float("nan"), False)
    yi, ni = divmod(best, N)
    depth = 1.0 / k[best]
    # pelvis in camera frame: (t * depth, depth); pose points at pelvis + M P
    pel_cam = np.array([t[best, 0] * depth, t[best, 1] * depth, depth])
    pts_cam = pel_cam + q[yi, ni]
    world = (pts_cam - camera.t) @ camera.R
    proj = camera.project(world)
    err = float(np.sqrt(np.mean(np.sum((proj[ok] - x[ok]) ** 2, 1))))
    res = ApproximatePose(world, err, ni, float(yaws[yi]), float(depth), True)
    obs = as_observer(observer)
    extra = {} if frame is None else {"frame": frame}
    obs.report("text", name=f"template/{camera.name}/approximate",
               text=f"database pose {database.sources[ni]} yaw {np.degrees(yaws[yi]):.0f} deg "
                    f"depth {depth:.2f} m error {err:.1f} px", camera=camera.name, **extra)
    obs.report("joints3d", joints=world, name=f"template/{camera.name}/approximate", skeleton=SKELETON_14, **extra)
    return res
