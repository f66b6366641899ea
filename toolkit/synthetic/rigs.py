"""Camera layouts of synthetic scenes and calibration perturbation.

``"broadcast"``: few cameras far away (25-45 m), elevated (6-15 m), on a wide
baseline (adjacent cameras 35-110 degrees apart), with focal lengths that make
the subject 100-250 px tall.  ``"studio"``: a ring of cameras at 3-5 m and
1.2-2.5 m high framing the whole working volume.

Novel (evaluation-only) cameras sit between the source cameras in azimuth, at
the same kind of distance and height, so that they see views no source camera
saw.
"""

from __future__ import annotations

import numpy as np

from toolkit.calibration.refine import apply_correction, calibration_error_px
from toolkit.cameras import Camera, Rig
from toolkit.errors import InputError

#: Subject height in pixels that broadcast cameras aim for (range from the issue).
BROADCAST_SUBJECT_PX = (100.0, 250.0)
#: Radius (metres) of the volume the subject moves in; cameras must keep it in view.
WORKING_RADIUS_M = 3.0


def _broadcast_camera(name, azimuth, rng, size, subject_height, centre):
    dist = rng.uniform(25.0, 45.0)
    elev = rng.uniform(6.0, 15.0)
    eye = centre + np.array([dist * np.cos(azimuth), dist * np.sin(azimuth), elev])
    target = centre + np.array([rng.uniform(-0.5, 0.5), rng.uniform(-0.5, 0.5), 0.9])
    px = rng.uniform(*BROADCAST_SUBJECT_PX) * size[1] / 720.0
    rng_d = np.linalg.norm(eye - target)
    focal = px * rng_d / subject_height
    # keep the working volume (a 3 m radius) in the image
    max_focal = 0.5 * min(size) * rng_d / (WORKING_RADIUS_M + 1.0)
    return Camera.look_at(name, eye, target, size=size, focal_px=min(focal, max_focal))


def _studio_camera(name, azimuth, rng, size, centre):
    dist = rng.uniform(3.5, 5.0)
    h = rng.uniform(1.2, 2.5)
    eye = centre + np.array([dist * np.cos(azimuth), dist * np.sin(azimuth), h])
    target = centre + np.array([0.0, 0.0, 0.95])
    # frame a 2.4 m tall, 2 m wide volume
    d = np.linalg.norm(eye - target)
    focal = min(0.5 * size[1] * d / 1.5, 0.5 * size[0] * d / 1.6)
    return Camera.look_at(name, eye, target, size=size, focal_px=focal)


def make_rig(layout: str, count: int, size: tuple[int, int], subject_height: float,
             rng: np.random.Generator | int | None = None, *, prefix: str = "cam",
             centre=(0.0, 0.0, 0.0), azimuths=None) -> Rig:
    """Cameras of a layout.

    Parameters
    ----------
    layout : {"broadcast", "studio"}
    count : int
        Number of cameras.
    size : tuple of int
        Image (width, height).
    subject_height : float
        Stature of the subject in metres (sets broadcast focal lengths).
    rng : numpy.random.Generator or int or None
    prefix : str
        Camera names are ``f"{prefix}{i:02d}"``.
    centre : array_like of shape (3,)
        Centre of the working volume on the ground.
    azimuths : array_like of shape (count,), optional
        Camera azimuths in radians (drawn from ``rng`` when omitted).

    Returns
    -------
    Rig
    """
    rng = np.random.default_rng(rng)
    if count < 1:
        raise InputError("cameras.count", "at least 1", str(count))
    centre = np.asarray(centre, float)
    if azimuths is None:
        azimuths = layout_azimuths(layout, count, rng)
    cams = []
    for i, az in enumerate(azimuths):
        name = f"{prefix}{i:02d}"
        if layout == "broadcast":
            cams.append(_broadcast_camera(name, az, rng, size, subject_height, centre))
        elif layout == "studio":
            cams.append(_studio_camera(name, az, rng, size, centre))
        else:
            raise InputError("cameras.layout", "'broadcast' or 'studio'", repr(layout))
    return Rig(tuple(cams))


def layout_azimuths(layout: str, count: int, rng: np.random.Generator) -> np.ndarray:
    """Camera azimuths (radians): a wide baseline for broadcast, a ring for studio."""
    start = rng.uniform(0, 2 * np.pi)
    if layout == "broadcast":
        steps = rng.uniform(np.radians(35), np.radians(110), max(count - 1, 0))
        return start + np.concatenate([[0.0], np.cumsum(steps)])
    return start + 2 * np.pi * np.arange(count) / count + rng.uniform(-0.15, 0.15, count)


def novel_rig(layout: str, source: Rig, count: int, subject_height: float,
              rng: np.random.Generator | int | None = None, centre=(0.0, 0.0, 0.0)) -> Rig:
    """Evaluation cameras between the source cameras (same layout and image size)."""
    rng = np.random.default_rng(rng)
    if count <= 0:
        return Rig(())
    c = np.asarray(centre, float)
    az = np.sort(np.array([np.arctan2(*(cam.center - c)[1::-1]) for cam in source]))
    # midpoints of the angular gaps between sorted source azimuths, smallest gaps first
    # (those are the views between cameras the pipeline is meant to interpolate)
    if len(az) == 1:
        mids = az + np.radians(30) * np.arange(1, count + 1)
    else:
        nxt = np.roll(az, -1)
        gaps = (nxt - az) % (2 * np.pi)
        order = np.argsort(gaps)
        mids = []
        k = 0
        while len(mids) < count:
            i = order[k % len(order)]
            frac = 0.5 if k < len(order) else rng.uniform(0.25, 0.75)
            mids.append(az[i] + frac * gaps[i])
            k += 1
        mids = np.array(mids)
    size = source[0].size
    return make_rig(layout, count, size, subject_height, rng, prefix="novel", centre=c, azimuths=mids)


def perturb_rig(rig: Rig, target_px: float, points: np.ndarray,
                rng: np.random.Generator | int | None = None) -> tuple[Rig, np.ndarray]:
    """Miscalibrate cameras so that the reprojection error of ``points`` is about ``target_px``.

    Each camera is rotated about a random axis through its centre by the
    angle that moves the image by ``target_px`` on average (a pure image shift
    to first order, which is how small calibration errors of distant broadcast
    cameras show), and its focal length is scaled by up to 0.5 %.

    Parameters
    ----------
    rig : Rig
        True cameras.
    target_px : float
        Wanted mean reprojection error in pixels (0 gives the rig unchanged).
    points : ndarray of shape (N, 3)
        World points the error is measured on (e.g. all ground-truth joints).
    rng : numpy.random.Generator or int or None

    Returns
    -------
    rig : Rig
        The perturbed ("measured") cameras.
    errors : ndarray of shape (n_cams,)
        Achieved mean reprojection error per camera, pixels.
    """
    rng = np.random.default_rng(rng)
    if target_px < 0 or not np.isfinite(target_px):
        raise InputError("cameras.calibration_error_px", "a finite value >= 0", str(target_px))
    pts = np.asarray(points, float).reshape(-1, 3)
    pts = pts[np.isfinite(pts).all(1)]
    out, errs = [], []
    for cam in rig:
        if target_px == 0:
            out.append(cam)
            errs.append(0.0)
            continue
        axis = rng.normal(size=3)
        axis /= np.linalg.norm(axis)
        fscale = 1.0 + rng.uniform(-0.005, 0.005)

        def make(angle):  # the same model the field-line refinement fits back
            return apply_correction(cam, axis * angle, np.log(fscale))

        def err(c):
            return calibration_error_px(c, cam, pts)

        angle = target_px / cam.K[0, 0]
        for _ in range(4):  # secant-like rescaling: error is nearly linear in the angle
            e = err(make(angle))
            if e <= 1e-9:
                break
            angle *= target_px / e
        c = make(angle)
        out.append(c)
        errs.append(err(c))
    return Rig(tuple(out)), np.array(errs)
