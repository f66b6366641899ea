"""Virtual cameras and camera paths for free-viewpoint video.

* :func:`orbit_path`: a circle around the subject at a given height, looking at it;
* :func:`interpolate_cameras`: a path through the source cameras, centres and
  orientations interpolated (slerp) and focal lengths blended;
* :func:`birds_eye`: a camera above all source cameras looking down at the subject.

All cameras are distortion-free pinhole cameras in OpenCV axes.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation, Slerp

from toolkit.cameras import Camera, Rig
from toolkit.errors import InputError

#: Default orbit radius, metres.
ORBIT_RADIUS_M = 6.0
#: Default orbit height, metres.
ORBIT_HEIGHT_M = 1.6
#: Height of the bird's-eye camera above the highest source camera, metres.
BIRDS_EYE_ABOVE_M = 4.0


def _check_target(target) -> np.ndarray:
    t = np.asarray(target, float)
    if t.shape != (3,) or not np.all(np.isfinite(t)):
        raise InputError("target", "a finite (3,) point in metres", f"{np.asarray(target).tolist()}")
    return t


def orbit_path(target, n_views: int, *, radius_m: float = ORBIT_RADIUS_M, height_m: float = ORBIT_HEIGHT_M,
               start_deg: float = 0.0, sweep_deg: float = 360.0, size=(1280, 720), focal_px: float = 1500.0,
               name: str = "orbit") -> list[Camera]:
    """Cameras on a horizontal circle around ``target``, each looking at it.

    Parameters
    ----------
    target : ndarray of shape (3,)
        Point looked at (e.g. the subject's pelvis), metres.
    n_views : int
        Number of cameras (>= 1).
    radius_m, height_m : float
        Circle radius and camera height above the ground, metres.
    start_deg, sweep_deg : float
        Azimuth of the first camera (0 = +x) and the swept angle, degrees.
    size : tuple of int
        Image ``(width, height)``.
    focal_px : float
        Focal length, pixels.
    name : str
        Camera names are ``f"{name}_{i:03d}"``.

    Returns
    -------
    list of Camera
    """
    t = _check_target(target)
    if n_views < 1 or radius_m <= 0:
        raise InputError("orbit_path", "n_views >= 1 and radius_m > 0", f"{n_views=}, {radius_m=}")
    end = sweep_deg if abs(sweep_deg) < 360 else sweep_deg * (n_views - 1) / max(n_views, 1)
    az = np.radians(start_deg + np.linspace(0.0, end, n_views))
    return [Camera.look_at(f"{name}_{i:03d}", [t[0] + radius_m * np.cos(a), t[1] + radius_m * np.sin(a), height_m],
                           t, size=size, focal_px=focal_px) for i, a in enumerate(az)]


def interpolate_cameras(a: Camera, b: Camera, s: float, name: str | None = None) -> Camera:
    """The camera a fraction ``s`` in [0, 1] of the way from ``a`` to ``b``.

    Centres are interpolated linearly, orientations by spherical linear
    interpolation, intrinsics linearly; ``b``'s image size must equal ``a``'s.
    At ``s = 0`` the result equals ``a`` (without distortion), at ``s = 1`` ``b``.
    """
    if tuple(a.size) != tuple(b.size):
        raise InputError("interpolate_cameras: b.size", f"{a.size} (a's size)", f"{b.size}")
    if not 0.0 <= s <= 1.0:
        raise InputError("interpolate_cameras: s", "a fraction in [0, 1]", f"{s}")
    rots = Rotation.from_matrix(np.stack([a.R, b.R]))
    R = Slerp([0.0, 1.0], rots)([s]).as_matrix()[0]
    c = (1 - s) * a.center + s * b.center
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = -R @ c
    K = (1 - s) * a.K + s * b.K
    return Camera(name or f"{a.name}-{b.name}@{s:.2f}", K, np.zeros(5), a.size, T)


def source_path(rig: Rig, n_views: int, *, closed: bool = False, name: str = "sweep") -> list[Camera]:
    """A path through the source cameras in rig order (optionally back to the first).

    The path passes through each source camera exactly (its pose and intrinsics).
    """
    cams = list(rig)
    if len(cams) < 2 or n_views < 2:
        raise InputError("source_path", "a rig of >= 2 cameras and n_views >= 2", f"{len(cams)} cameras, {n_views=}")
    if closed:
        cams = cams + [cams[0]]
    n_seg = len(cams) - 1
    out = []
    for i, x in enumerate(np.linspace(0.0, n_seg, n_views)):
        k = min(int(np.floor(x)), n_seg - 1)
        out.append(interpolate_cameras(cams[k], cams[k + 1], float(x - k), name=f"{name}_{i:03d}"))
    return out


def birds_eye(rig: Rig, target, *, above_m: float = BIRDS_EYE_ABOVE_M, size=None, focal_px: float | None = None,
              name: str = "birds_eye") -> Camera:
    """A camera above all source cameras, looking down at ``target``.

    It stands over the mean horizontal position of the source cameras pulled
    halfway towards the target, ``above_m`` higher than the highest camera.
    """
    t = _check_target(target)
    c = rig.centers
    if len(c) == 0:
        raise InputError("birds_eye: rig", "at least one camera", "an empty rig")
    eye = 0.5 * (c.mean(0) + t)
    eye[2] = c[:, 2].max() + above_m
    size = tuple(rig[0].size) if size is None else size
    f = float(rig[0].K[0, 0]) if focal_px is None else focal_px
    return Camera.look_at(name, eye, t, up=(0.0, 0.0, 1.0), size=size, focal_px=f)
