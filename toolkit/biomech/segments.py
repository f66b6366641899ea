"""Anatomical segment frames built from 3D joint centres (and, where given, a few markers).

Every frame is a rotation matrix whose columns are the segment's axes in the
world, in the ISB convention (Wu et al. 2002, 2005, *J Biomech* 35:543-548
and 38:981-992): **X anterior, Y superior (along the segment, distal to
proximal), Z to the person's right**.  The same right-handed convention is
used on both sides; :mod:`toolkit.biomech.angles` flips the signs of the
left side's ab/adduction and rotation so that both sides read as Plug-in Gait
reports them.

The frames need only the joints every system of the toolkit estimates (hips,
knees, ankles, shoulders, elbows, wrists, neck); optional landmarks refine
them:

* pelvis: ``l_asis``, ``r_asis``, ``l_psis``, ``r_psis`` (the pelvis markers
  of a marker capture) give the pelvis its tilt; without them the pelvis's
  vertical is the trunk's (mid-hip to neck), which differs from an
  ASIS/PSIS pelvis by the pelvic tilt (see ``docs/joint_angles.md``);
* thorax: ``c7``, ``t10``, ``clav``, ``strn`` (Plug-in Gait's thorax
  markers) give the thorax its own axes; without them its vertical is the
  trunk's and its lateral axis the shoulder line;
* thigh and shank: ``<side>_knee_lateral`` and ``<side>_ankle_lateral`` (a
  marker on the lateral epicondyle or malleolus, on the joint's flexion axis)
  give the lateral axis as a marker-based model such as Plug-in Gait defines
  it (knee centre to knee marker);
* foot: ``<side>_toe`` gives the foot its long axis (ankle centre to toe);
  with ``<side>_heel`` too, the axis is turned by the median pitch of
  heel-to-toe against ankle-to-toe, so that a level foot reads 0: measured in
  a static trial when one is given (:func:`foot_pitch_offsets`, Plug-in
  Gait's plantarflexion offset), else over the trial itself; without a toe
  the foot and the ankle angle are not defined.

A long bone's third axis comes from the plane of the limb when the middle
joint is bent (hip-knee-ankle, shoulder-elbow-wrist), blended continuously
with the proximal segment's lateral axis as the limb straightens (the plane's
normal is weighted by the sine of the bend): a straight limb's rotation about
its own axis is not observable from three joint centres.
"""

from __future__ import annotations

import numpy as np

from toolkit.errors import InputError

#: Weight of the proximal segment's lateral axis against the limb plane's normal (whose length is the
#: sine of the bend): the plane takes over from about 15 degrees of knee or elbow flexion.
PLANE_BLEND = float(np.sin(np.deg2rad(15.0)))


def _unit(v: np.ndarray) -> np.ndarray:
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(n > 1e-12, v / n, np.nan)


def _reject(v: np.ndarray, axis: np.ndarray) -> np.ndarray:
    """The part of ``v`` (T, 3) perpendicular to the unit ``axis`` (T, 3)."""
    return v - np.sum(v * axis, -1, keepdims=True) * axis


def frame_from_axes(y: np.ndarray, z_hint: np.ndarray) -> np.ndarray:
    """Rotation (T, 3, 3) with columns (X, Y, Z): Y along ``y``, Z the part of ``z_hint`` normal to it.

    Parameters
    ----------
    y : ndarray of shape (T, 3)
        Superior axis (any length).
    z_hint : ndarray of shape (T, 3)
        Rough right-lateral axis; only its part perpendicular to ``y`` is used.

    Returns
    -------
    ndarray of shape (T, 3, 3)
        NaN where either vector is missing or they are parallel.
    """
    Y = _unit(y)
    Z = _unit(_reject(z_hint, Y))
    X = np.cross(Y, Z)
    return np.stack([X, Y, Z], -1)


def frame_from_forward(x: np.ndarray, z_hint: np.ndarray) -> np.ndarray:
    """Rotation (T, 3, 3): X along ``x`` (the foot's long axis), Z the part of ``z_hint`` normal to it."""
    X = _unit(x)
    Z = _unit(_reject(z_hint, X))
    Y = np.cross(Z, X)
    return np.stack([X, Y, Z], -1)


def _limb_lateral(proximal, middle, distal, reference_z) -> np.ndarray:
    """Right-lateral axis of a limb (T, 3): the limb plane's normal blended with the reference's Z."""
    a = _unit(proximal - middle)
    b = _unit(distal - middle)
    # knee bent: a x b points to the right for either leg; the elbow bends the other way
    n = np.cross(a, b)
    return n + PLANE_BLEND * reference_z


def _foot_pitch_offset(foot: np.ndarray, heel_to_toe: np.ndarray) -> float:
    """Median angle (radians) from the foot's X axis up to the heel-to-toe line, about the foot's Z."""
    x = np.einsum("tij,ti->tj", foot, heel_to_toe)     # heel-to-toe in the foot's frame
    pitch = np.arctan2(x[:, 1], x[:, 0])
    ok = np.isfinite(pitch)
    return float(np.median(pitch[ok])) if ok.any() else 0.0


def _pitch(frame: np.ndarray, angle_rad: float) -> np.ndarray:
    """``frame`` (T, 3, 3) turned by ``angle_rad`` about its own Z axis (X towards Y)."""
    c, s = np.cos(angle_rad), np.sin(angle_rad)
    return frame @ np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def foot_pitch_offsets(points: dict) -> dict:
    """Per side, the median pitch (radians) of heel-to-toe against ankle-to-toe in the foot's frame.

    Parameters
    ----------
    points : dict of str to ndarray of shape (T, 3)
        Landmarks of a static trial (or any trial), with ``<side>_toe`` and ``<side>_heel``.

    Returns
    -------
    dict of str to float
        ``{"l": angle, "r": angle}`` for the sides with a toe and a heel.
    """
    frames = segment_frames({k: v for k, v in points.items() if not k.endswith("_heel")})
    return {side: _foot_pitch_offset(frames[f"{side}_foot"], points[f"{side}_toe"] - points[f"{side}_heel"])
            for side in ("l", "r") if f"{side}_foot" in frames and f"{side}_heel" in points}


def segment_frames(points: dict, foot_offsets: dict | None = None) -> dict:
    """Frames of the pelvis, thorax and limb segments from named 3D points.

    Parameters
    ----------
    points : dict of str to ndarray of shape (T, 3)
        Metres, world frame, NaN = missing.  Required: ``l_hip``, ``r_hip``,
        ``neck`` (or both shoulders).  Used when present: ``l_/r_`` ``knee``,
        ``ankle``, ``shoulder``, ``elbow``, ``wrist``, ``toe``, ``heel``,
        ``asis``, ``psis``, ``knee_lateral``, ``ankle_lateral``; ``c7``,
        ``t10``, ``clav``, ``strn``.
    foot_offsets : dict of str to float, optional
        ``{"l": rad, "r": rad}``: the foot's pitch offsets from a static trial
        (:func:`foot_pitch_offsets`); by default measured over ``points``
        when a heel is given.

    Returns
    -------
    dict of str to ndarray of shape (T, 3, 3)
        ``pelvis``, ``thorax`` and, where their joints are present,
        ``<side>_thigh``, ``<side>_shank``, ``<side>_foot``,
        ``<side>_upper_arm``, ``<side>_forearm``; columns (X anterior,
        Y superior, Z right); NaN in frames where a point is missing.

    Raises
    ------
    InputError
        Without hips, or without a neck and shoulders; arrays of other shapes.
    """
    p = {}
    T = None
    for k, v in points.items():
        a = np.asarray(v, float)
        if a.ndim != 2 or a.shape[1] != 3 or (T is not None and len(a) != T):
            raise InputError(f"points[{k!r}]", f"an array of shape ({T if T is not None else 'T'}, 3)",
                             f"shape {a.shape}")
        T = len(a)
        p[k] = a
    missing = [k for k in ("l_hip", "r_hip") if k not in p]
    if missing:
        raise InputError("points", "hip joint centres 'l_hip' and 'r_hip'", f"no {missing}")
    if "neck" not in p:
        if "l_shoulder" in p and "r_shoulder" in p:
            p["neck"] = 0.5 * (p["l_shoulder"] + p["r_shoulder"])
        else:
            raise InputError("points", "'neck' or both shoulders", f"keys {sorted(p)}")
    mid_hip = 0.5 * (p["l_hip"] + p["r_hip"])
    trunk_up = p["neck"] - mid_hip
    hip_right = p["r_hip"] - p["l_hip"]
    frames = {}
    if all(k in p for k in ("l_asis", "r_asis", "l_psis", "r_psis")):
        right = p["r_asis"] - p["l_asis"]
        fwd = 0.5 * (p["l_asis"] + p["r_asis"]) - 0.5 * (p["l_psis"] + p["r_psis"])
        Z = _unit(right)
        X = _unit(_reject(fwd, Z))
        frames["pelvis"] = np.stack([X, np.cross(Z, X), Z], -1)
    else:
        frames["pelvis"] = frame_from_axes(trunk_up, hip_right)
    if all(k in p for k in ("c7", "t10", "clav", "strn")):
        up = 0.5 * (p["clav"] + p["c7"]) - 0.5 * (p["strn"] + p["t10"])
        fwd = 0.5 * (p["clav"] + p["strn"]) - 0.5 * (p["c7"] + p["t10"])
        Y = _unit(up)
        X = _unit(_reject(fwd, Y))
        frames["thorax"] = np.stack([X, Y, np.cross(X, Y)], -1)
    elif "l_shoulder" in p and "r_shoulder" in p:
        frames["thorax"] = frame_from_axes(trunk_up, p["r_shoulder"] - p["l_shoulder"])
    else:
        frames["thorax"] = frame_from_axes(trunk_up, hip_right)
    for side in ("l", "r"):
        j = {k[2:]: v for k, v in p.items() if k.startswith(f"{side}_")}
        outward = 1.0 if side == "r" else -1.0     # a lateral marker minus the centre, times this, points right
        if "knee" in j:
            ref = frames["pelvis"][..., 2]
            if "knee_lateral" in j:
                lat = outward * (j["knee_lateral"] - j["knee"])
            elif "ankle" in j:
                lat = _limb_lateral(j["hip"], j["knee"], j["ankle"], ref)
            else:
                lat = ref
            frames[f"{side}_thigh"] = frame_from_axes(j["hip"] - j["knee"], lat)
            if "ankle" in j:
                lat = (outward * (j["ankle_lateral"] - j["ankle"]) if "ankle_lateral" in j
                       else frames[f"{side}_thigh"][..., 2])
                frames[f"{side}_shank"] = shank = frame_from_axes(j["knee"] - j["ankle"], lat)
                if "toe" in j:
                    foot = frame_from_forward(j["toe"] - j["ankle"], shank[..., 2])
                    if foot_offsets is not None and side in foot_offsets:
                        foot = _pitch(foot, float(foot_offsets[side]))
                    elif "heel" in j:
                        foot = _pitch(foot, _foot_pitch_offset(foot, j["toe"] - j["heel"]))
                    frames[f"{side}_foot"] = foot
        if "shoulder" in j and "elbow" in j:
            ref = frames["thorax"][..., 2]
            lat = -_limb_lateral(j["shoulder"], j["elbow"], j["wrist"], -ref) if "wrist" in j else ref
            frames[f"{side}_upper_arm"] = frame_from_axes(j["shoulder"] - j["elbow"], lat)
            if "wrist" in j:
                frames[f"{side}_forearm"] = frame_from_axes(j["elbow"] - j["wrist"],
                                                            frames[f"{side}_upper_arm"][..., 2])
    return frames
