"""Camera layouts of synthetic scenes and calibration perturbation.

``"broadcast"``: few cameras far away (25-45 m), elevated (6-15 m), on a wide
baseline (adjacent cameras 35-110 degrees apart), with focal lengths that make
the subject 100-250 px tall.  ``"studio"``: a ring of cameras at 3-5 m and
1.2-2.5 m high framing the whole working volume.  ``"trinocular"``: heads of three
parallel cameras (an L: a reference, one ``baseline_m`` to its right, one
``baseline_m`` above it; cameras ``3k, 3k+1, 3k+2`` form head ``k``) 2-4 m from
the subject, 1.0-1.6 m high, framing a 2.6 m tall volume (stereo, issue 18).

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


def _broadcast_camera(name, azimuth, rng, size, subject_height, centre, subject_px=None,
                      working_radius_m=WORKING_RADIUS_M, high=False):
    dist = rng.uniform(25.0, 45.0)
    elev = rng.uniform(6.0, 15.0)
    if high:  # a high view (a spider cam, a roof camera): 40-60 degrees above the horizon
        elev = dist * np.tan(np.radians(rng.uniform(40.0, 60.0)))
    eye = centre + np.array([dist * np.cos(azimuth), dist * np.sin(azimuth), elev])
    target = centre + np.array([rng.uniform(-0.5, 0.5), rng.uniform(-0.5, 0.5), 0.9])
    px = rng.uniform(*BROADCAST_SUBJECT_PX) * size[1] / 720.0
    if subject_px is not None:  # asked for: same draws, another size
        px = float(np.interp(px, np.array(BROADCAST_SUBJECT_PX) * size[1] / 720.0, subject_px))
    rng_d = np.linalg.norm(eye - target)
    focal = px * rng_d / subject_height
    # keep the working volume (a 3 m radius, or the motion's own when given) in the image
    max_focal = 0.5 * min(size) * rng_d / (working_radius_m + 1.0)
    return Camera.look_at(name, eye, target, size=size, focal_px=min(focal, max_focal))


def _studio_camera(name, azimuth, rng, size, centre, high=False):
    dist = rng.uniform(3.5, 5.0)
    h = rng.uniform(1.2, 2.5)
    if high:  # a ceiling camera 35-55 degrees above the subject's middle
        h = 0.95 + dist * np.tan(np.radians(rng.uniform(35.0, 55.0)))
    eye = centre + np.array([dist * np.cos(azimuth), dist * np.sin(azimuth), h])
    target = centre + np.array([0.0, 0.0, 0.95])
    # frame a 2.4 m tall, 2 m wide volume
    d = np.linalg.norm(eye - target)
    focal = min(0.5 * size[1] * d / 1.5, 0.5 * size[0] * d / 1.6)
    return Camera.look_at(name, eye, target, size=size, focal_px=focal)


#: Distance (metres) of a trinocular head from the subject's vertical axis.
TRINOCULAR_DISTANCE_M = (2.0, 4.0)
#: Default distance (metres) between a trinocular head's reference camera and the two others.
TRINOCULAR_BASELINE_M = (0.2, 0.4)


def _trinocular_head(names, azimuth, rng, size, centre, baseline_m):
    """Three parallel cameras: the reference, one to its right, one above it (``baseline_m`` = (lo, hi))."""
    dist = rng.uniform(*TRINOCULAR_DISTANCE_M)
    eye = centre + np.array([dist * np.cos(azimuth), dist * np.sin(azimuth), rng.uniform(1.0, 1.6)])
    target = centre + np.array([0.0, 0.0, 0.95])
    d = np.linalg.norm(eye - target)
    focal = min(0.5 * size[1] * d / 1.3, 0.5 * size[0] * d / 1.3)
    ref = Camera.look_at(names[0], eye, target, size=size, focal_px=focal)
    b = rng.uniform(baseline_m[0], baseline_m[1], 2)
    offsets = (ref.R[0] * b[0], -ref.R[1] * b[1])  # the reference's x (right) and -y (up) axes
    return [ref] + [Camera.look_at(n, eye + o, target + o, size=size, focal_px=focal)
                    for n, o in zip(names[1:], offsets)]


def camera_names(count: int, prefix: str = "cam") -> list[str]:
    """The names :func:`make_rig` gives ``count`` cameras: ``f"{prefix}{i:02d}"``."""
    return [f"{prefix}{i:02d}" for i in range(count)]


def make_rig(layout: str, count: int, size: tuple[int, int], subject_height: float,
             rng: np.random.Generator | int | None = None, *, prefix: str = "cam",
             centre=(0.0, 0.0, 0.0), azimuths=None, spacing_deg=None, subject_px=None,
             working_radius_m: float = WORKING_RADIUS_M, high=None, baseline_m=None) -> Rig:
    """Cameras of a layout.

    Parameters
    ----------
    layout : {"broadcast", "studio", "trinocular"}
    count : int
        Number of cameras (trinocular: 3 per head, ``count // 3`` heads, the
        heads' azimuths from ``azimuths``/``spacing_deg`` as a studio ring).
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
    spacing_deg : tuple of float, optional
        ``(lo, hi)`` range of the azimuth between neighbouring cameras, degrees
        (default: the layout's, see :func:`layout_azimuths`).
    subject_px : tuple of float, optional
        Broadcast: ``(lo, hi)`` subject height in pixels (default 100-250 at 720 rows).
    working_radius_m : float
        Radius of the volume the subject moves in, metres (broadcast focal lengths keep it in view).
    high : array_like of bool of shape (count,), optional
        Cameras placed high above the subject (40-60 degrees broadcast, 35-55 studio).
    baseline_m : tuple of float, optional
        Trinocular: ``(lo, hi)`` distance in metres from a head's reference camera to the two others
        (default :data:`TRINOCULAR_BASELINE_M`).

    Returns
    -------
    Rig
    """
    rng = np.random.default_rng(rng)
    if count < 1:
        raise InputError("cameras.count", "at least 1", str(count))
    centre = np.asarray(centre, float)
    if layout == "trinocular":
        if count % 3:
            raise InputError("cameras.count", "3 cameras per trinocular head", str(count))
        az = layout_azimuths("studio", count // 3, rng, spacing_deg) if azimuths is None else azimuths
        names = camera_names(count, prefix)
        return Rig(tuple(c for k, a in enumerate(az)
                         for c in _trinocular_head(names[3 * k:3 * k + 3], a, rng, size, centre,
                                                  baseline_m or TRINOCULAR_BASELINE_M)))
    if azimuths is None:
        azimuths = layout_azimuths(layout, count, rng, spacing_deg)
    high = np.zeros(len(azimuths), bool) if high is None else np.asarray(high, bool)
    cams = []
    for i, (name, az) in enumerate(zip(camera_names(len(azimuths), prefix), azimuths)):
        if layout == "broadcast":
            cams.append(_broadcast_camera(name, az, rng, size, subject_height, centre, subject_px,
                                          working_radius_m, bool(high[i])))
        elif layout == "studio":
            cams.append(_studio_camera(name, az, rng, size, centre, bool(high[i])))
        else:
            raise InputError("cameras.layout", "'broadcast', 'studio' or 'trinocular'", repr(layout))
    return Rig(tuple(cams))


def layout_azimuths(layout: str, count: int, rng: np.random.Generator, spacing_deg=None) -> np.ndarray:
    """Camera azimuths (radians): a wide baseline for broadcast, a ring for studio.

    With ``spacing_deg = (lo, hi)`` neighbouring cameras of either layout are
    ``uniform(lo, hi)`` degrees apart (an arc of ``count`` cameras).
    """
    start = rng.uniform(0, 2 * np.pi)
    if spacing_deg is not None:
        steps = rng.uniform(np.radians(spacing_deg[0]), np.radians(spacing_deg[1]), max(count - 1, 0))
        return start + np.concatenate([[0.0], np.cumsum(steps)])
    if layout == "broadcast":
        steps = rng.uniform(np.radians(35), np.radians(110), max(count - 1, 0))
        return start + np.concatenate([[0.0], np.cumsum(steps)])
    return start + 2 * np.pi * np.arange(count) / count + rng.uniform(-0.15, 0.15, count)


def novel_rig(layout: str, source: Rig, count: int, subject_height: float,
              rng: np.random.Generator | int | None = None, centre=(0.0, 0.0, 0.0), placement: str = "between",
              subject_px=None, working_radius_m: float = WORKING_RADIUS_M) -> Rig:
    """Evaluation cameras (same layout and image size as the sources).

    Parameters
    ----------
    layout : {"broadcast", "studio"}
    source : Rig
    count : int
    subject_height : float
    rng : numpy.random.Generator or int or None
    centre : array_like of shape (3,)
    placement : {"between", "around"}
        ``"between"``: in the angular gaps between the source cameras, smallest
        gaps first.  ``"around"``: all around the subject: the first camera at the
        reverse angle (opposite the sources' mean direction, where every billboard
        is seen from behind), the others evenly spread (+-10 degrees) with every
        second one a high view.
    subject_px, working_radius_m
        As in :func:`make_rig`.
    """
    rng = np.random.default_rng(rng)
    if count <= 0:
        return Rig(())
    layout = "studio" if layout == "trinocular" else layout  # single evaluation cameras at studio distances
    c = np.asarray(centre, float)
    size = source[0].size
    kw = dict(prefix="novel", centre=c, subject_px=subject_px, working_radius_m=working_radius_m)
    if placement == "around":
        dirs = np.array([(cam.center - c)[:2] / np.linalg.norm((cam.center - c)[:2]) for cam in source])
        mean = dirs.sum(0)
        back = np.arctan2(-mean[1], -mean[0]) if np.linalg.norm(mean) > 1e-6 else rng.uniform(0, 2 * np.pi)
        az = back + 2 * np.pi * np.arange(count) / count + np.r_[0.0, rng.uniform(-1, 1, count - 1) * np.radians(10)]
        high = np.arange(count) % 2 == 1
        return make_rig(layout, count, size, subject_height, rng, azimuths=az, high=high, **kw)
    if placement != "between":
        raise InputError("novel.placement", "'between' or 'around'", repr(placement))
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
    return make_rig(layout, count, size, subject_height, rng, azimuths=mids, **kw)


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
