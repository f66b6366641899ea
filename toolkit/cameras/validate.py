"""Cameras checked against the physical range their parameters can mean.

A :class:`~toolkit.cameras.Camera` only checks that its numbers are well
formed (finite, a rotation, a positive size).  A calibration file can hold
well-formed numbers that no real camera has: a principal point a billion
pixels away, distortion coefficients of a million, or a pose written in the
other convention (``world_from_cam`` where ``cam_from_world`` is meant, or a
translation with its sign flipped).  Such a calibration does not fail later:
it gives results that are metres off, or asks for terabytes of memory.  Every
calibration reader therefore passes its cameras through :func:`check_camera`
and its rig through :func:`check_rig`, which raise an
:class:`~toolkit.errors.InputError` naming the file, the camera, the field,
what was expected and what was found.

The checks, and why each bound:

* image size at most :data:`MAX_IMAGE_SIDE` pixels a side (no video format
  goes beyond it; a larger size is a unit or field mix-up and would be
  allocated as is);
* principal point inside the image (pixel centres from 0 to ``size - 1``, with
  half a pixel of edge): a lens's optical axis goes through its sensor;
* a field of view of at least :data:`MIN_FOV_DEG` degrees (a focal length in
  pixels of at most ``size / (2 tan(MIN_FOV_DEG / 2))``);
* lens distortion that keeps the image monotonic: along every ray from the
  principal point to the image's corners and edge midpoints the distorted
  radius grows with the undistorted one until it reaches the image edge, and
  it reaches the edge at an undistorted radius within a factor
  :data:`MAX_DISTORTION_SCALE` of the distorted one (no lens bends the image
  by more; coefficients of ``±1e6`` do);
* for a rig whose optical axes converge (spread over more than
  :data:`CONVERGING_SPREAD_DEG`), the point nearest every optical axis, which
  is where the cameras look together, is in front of every camera and inside
  its image: a pose in the wrong convention or a flipped translation puts it
  behind them or out of their pictures.  (A rig whose axes are nearly
  parallel is not checked this way: it says nothing of where the scene is.)

A pose in the wrong convention is not always visible in the calibration alone
(the cameras of a level ring written as ``world_from_cam`` all look the same
way, as some real rigs do); the results then show it: :func:`cameras_behind`
names the cameras that see a reconstructed point lying behind them, which no
camera can, so the systems that reconstruct 3D joints refuse such a frame or
calibration instead of reporting it as a success.
"""

from __future__ import annotations

import cv2
import numpy as np

from toolkit.cameras.camera import Camera, Rig
from toolkit.errors import InputError

__all__ = ["MAX_IMAGE_SIDE", "MIN_FOV_DEG", "MAX_DISTORTION_SCALE", "CONVERGING_SPREAD_DEG", "cameras_behind",
           "check_camera", "check_rig"]

#: Largest image side accepted, pixels (16K video is 15360 wide).
MAX_IMAGE_SIDE = 32768
#: Narrowest horizontal or vertical field of view accepted, degrees (a 2000 mm lens on a full-frame sensor is 1.0).
MIN_FOV_DEG = 0.1
#: Largest ratio between the undistorted and the distorted radius of the image edge (either way); strong
#: wide-angle lenses calibrated with the pinhole model stay within 2.
MAX_DISTORTION_SCALE = 4.0
#: Spread of the optical axes (largest angle between two) above which a rig is taken to look at one scene.
CONVERGING_SPREAD_DEG = 30.0
#: Samples along each ray of the distortion check.
_RADIAL_SAMPLES = 4000


def _edge_points(camera: Camera) -> np.ndarray:
    """The image's corners and edge midpoints (pixel edges), (8, 2) pixels."""
    w, h = camera.size
    xs, ys = (-0.5, (w - 1) / 2, w - 0.5), (-0.5, (h - 1) / 2, h - 0.5)
    return np.array([(x, y) for x in xs for y in ys if not (x == xs[1] and y == ys[1])])


def _distortion_problem(camera: Camera) -> str | None:
    """Why the lens distortion does not keep the image monotonic, or None when it does."""
    if not camera.has_distortion:
        return None
    K = camera.K
    uv = _edge_points(camera)
    y = (uv[:, 1] - K[1, 2]) / K[1, 1]
    x = (uv[:, 0] - K[0, 2] - K[0, 1] * y) / K[0, 0]
    targets = np.hypot(x, y)  # distorted radius of each edge point, normalised image coordinates
    directions = np.stack([x, y], axis=1) / np.maximum(targets, 1e-12)[:, None]
    for target, d in zip(targets, directions):
        if target < 1e-9:
            continue
        r = np.linspace(0.0, target * MAX_DISTORTION_SCALE, _RADIAL_SAMPLES)
        pts = np.concatenate([r[:, None] * d, np.ones((r.size, 1))], axis=1)
        dist_pts, _ = cv2.projectPoints(pts.reshape(-1, 1, 3), np.zeros(3), np.zeros(3), np.eye(3), camera.dist)
        s = np.linalg.norm(dist_pts.reshape(-1, 2), axis=1)
        if not np.all(np.isfinite(s)):
            return "non-finite distorted points"
        reach = np.flatnonzero(s >= target)
        last = reach[0] if reach.size else r.size - 1
        if np.any(np.diff(s[: last + 1]) <= 0):
            k = int(np.flatnonzero(np.diff(s[: last + 1]) <= 0)[0])
            return (f"a distorted radius that stops growing at {r[k]:.3g} (normalised), inside the image "
                    f"(its edge is at {target:.3g})")
        if not reach.size:
            return (f"the image edge at {target:.3g} (normalised) reached only beyond {r[-1]:.3g}: the lens "
                    f"would shrink the image more than {MAX_DISTORTION_SCALE:g} times")
        if r[last] * MAX_DISTORTION_SCALE < target:
            return (f"the image edge at {target:.3g} (normalised) reached at {r[last]:.3g}: the lens would "
                    f"stretch the image more than {MAX_DISTORTION_SCALE:g} times")
    return None


def check_camera(camera: Camera, where: str = "camera") -> Camera:
    """Raise unless ``camera``'s intrinsics lie in the physical range (see the module docstring).

    Parameters
    ----------
    camera : Camera
    where : str
        The file and table the camera came from, named in the error.

    Returns
    -------
    Camera
        ``camera`` itself.

    Raises
    ------
    InputError
        Image size, principal point, focal length or distortion out of range.
    """
    w, h = camera.size
    if max(w, h) > MAX_IMAGE_SIDE:
        raise InputError(f"{where}.size", f"an image of at most {MAX_IMAGE_SIDE} pixels a side", f"{w} x {h}")
    K = camera.K
    cx, cy = K[0, 2], K[1, 2]
    if not (-0.5 <= cx <= w - 0.5 and -0.5 <= cy <= h - 0.5):
        raise InputError(f"{where}.matrix", f"a principal point (cx, cy) inside the {w} x {h} image "
                         f"(between -0.5 and {w - 0.5:g}, {h - 0.5:g})", f"({cx:.6g}, {cy:.6g})")
    f_max = 0.5 * max(w, h) / np.tan(np.radians(MIN_FOV_DEG) / 2)
    if K[0, 0] > f_max or K[1, 1] > f_max:
        raise InputError(f"{where}.matrix", f"focal lengths fx, fy of at most {f_max:.4g} px (a field of view of "
                         f"at least {MIN_FOV_DEG:g} degrees)", f"fx {K[0, 0]:.6g}, fy {K[1, 1]:.6g}")
    problem = _distortion_problem(camera)
    if problem is not None:
        raise InputError(f"{where}.distortions", "lens distortion that keeps the image monotonic (each image point "
                         "the image of one ray)", f"{camera.dist.tolist()}: {problem}")
    return camera


def _nearest_to_axes(rig: Rig) -> np.ndarray | None:
    """The point nearest every optical axis (least squares), or None when the axes are nearly parallel."""
    A = np.zeros((3, 3))
    b = np.zeros(3)
    for cam in rig:
        d = cam.forward
        P = np.eye(3) - np.outer(d, d)
        A += P
        b += P @ cam.center
    if np.linalg.eigvalsh(A)[0] < 1e-3 * len(rig):
        return None
    return np.linalg.solve(A, b)


def check_rig(rig: Rig, where: str = "rig") -> Rig:
    """Raise unless every camera of ``rig`` passes :func:`check_camera` and a converging rig looks forward.

    Parameters
    ----------
    rig : Rig
    where : str
        The calibration file, named in the error.

    Returns
    -------
    Rig
        ``rig`` itself.

    Raises
    ------
    InputError
        A camera out of range, or the point the cameras look at together behind one of them.
    """
    for cam in rig:
        check_camera(cam, f"{where}: [{cam.name}]")
    if len(rig) < 2:
        return rig
    fwd = np.array([c.forward for c in rig])
    spread = np.degrees(np.arccos(np.clip(fwd @ fwd.T, -1.0, 1.0))).max()
    if spread < CONVERGING_SPREAD_DEG:
        return rig
    p = _nearest_to_axes(rig)
    if p is None:
        return rig
    behind = [c.name for c in rig if c.depth_of(p) <= 0]
    outside = [c.name for c in rig if c.name not in behind and not c.in_image(c.project(p))]
    if behind or outside:
        found = ", ".join(([f"behind {behind}"] if behind else []) + ([f"outside the image of {outside}"]
                                                                        if outside else []))
        raise InputError(f"{where}: rotation/translation", "cam_from_world poses (world to camera, metres) that put "
                         "the point the cameras look at together in front of every camera, inside its image",
                         f"that point {np.round(p, 3).tolist()} {found} (a world_from_cam pose, or a "
                         "translation of the other sign?)")
    return rig


def cameras_behind(rig: Rig, points: np.ndarray, seen: np.ndarray) -> list[str]:
    """The cameras of ``rig`` that see one of ``points`` lying behind them (or on their centre plane).

    No camera sees a point behind it, so a reconstruction that puts a point
    there from that camera's observation comes from a wrong calibration (a
    ``world_from_cam`` pose, a flipped translation), however well its rays meet.

    Parameters
    ----------
    rig : Rig
        ``C`` cameras.
    points : ndarray of shape (J, 3)
        Reconstructed points (e.g. 3D joints), metres, world; NaN = missing (never behind).
    seen : ndarray of shape (C, J), bool
        Whether camera ``c`` observed point ``j`` (a finite 2D keypoint or joint in its image).

    Returns
    -------
    list of str
        Names of those cameras, rig order (empty: every point lies in front of the cameras that see it).

    Raises
    ------
    InputError
        ``points`` or ``seen`` of another shape.

    Examples
    --------
    >>> cameras_behind(rig, joints3d, np.isfinite(poses2d).all(axis=-1))  # doctest: +SKIP
    []
    """
    pts = np.asarray(points, float)
    if pts.ndim != 2 or pts.shape[1] != 3:
        raise InputError("cameras_behind: points", "an array of shape (J, 3), metres", f"shape {pts.shape}")
    vis = np.asarray(seen, bool)
    if vis.shape != (len(rig), len(pts)):
        raise InputError("cameras_behind: seen", f"an array of shape (C, J) = ({len(rig)}, {len(pts)})",
                         f"shape {vis.shape}")
    finite = np.isfinite(pts).all(axis=1)
    out = []
    for c, cam in enumerate(rig):
        if not (vis[c] & finite).any():
            continue
        z = cam.depth_of(pts[vis[c] & finite])
        if (z <= 0).any():
            out.append(cam.name)
    return out
