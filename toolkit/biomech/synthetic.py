"""Synthetic skeletons posed by known joint angles (the ground truth of the joint-angle tests and benchmark).

The segments are built as :mod:`toolkit.biomech.segments` defines them (X
anterior, Y superior, Z right), each distal frame the proximal one turned by
the Cardan Z-X-Y angles of :mod:`toolkit.biomech.angles`; joint centres are
then placed along the segments' Y axes, so that the angles computed from the
points must come back exactly.
"""

from __future__ import annotations

import numpy as np

from toolkit.biomech.angles import ANGLE_DEFINITIONS, rotation_zxy

#: Segment lengths of the synthetic person, metres.
LENGTHS = {"thigh": 0.42, "shank": 0.40, "foot": 0.15, "upper_arm": 0.30, "forearm": 0.26, "trunk": 0.50,
           "pelvis_half": 0.09, "shoulder_half": 0.18}
#: Distance of the lateral knee and ankle markers from the joint centres, metres.
LATERAL_MARKER_M = 0.05


def _signs(joint):
    for name, _, _, motions in ANGLE_DEFINITIONS:
        if name == joint:
            return {m: (idx, sr, sl) for m, idx, sr, sl in motions}
    raise KeyError(joint)


def _relative(joint: str, side: str, values: dict, T: int) -> np.ndarray:
    """Rotation (T, 3, 3) of the distal segment in the proximal one for the given angles (degrees)."""
    cardan = np.zeros((T, 3))
    for motion, (idx, sr, sl) in _signs(joint).items():
        v = values.get(f"{side}_{joint}_{motion}")
        if v is not None:
            cardan[:, idx] = np.asarray(v, float) * (sr if side == "r" else sl)
    return rotation_zxy(cardan)


#: Range of each angle of :func:`smooth_motion`, degrees (a wide gait-and-reach repertoire).
MOTION_RANGES = {"hip_flexion": (-15, 60), "hip_adduction": (-15, 15), "hip_rotation": (-20, 20),
                 "knee_flexion": (10, 100), "ankle_dorsiflexion": (-25, 20), "shoulder_flexion": (-30, 70),
                 "shoulder_abduction": (0, 50), "shoulder_rotation": (-20, 20), "elbow_flexion": (15, 120)}


def smooth_motion(n_frames: int, rng: np.random.Generator | int | None = None) -> dict:
    """Angles (degrees) of every joint over ``n_frames``: one sine cycle each, random phase.

    Parameters
    ----------
    n_frames : int
    rng : numpy.random.Generator or int or None

    Returns
    -------
    dict of str to ndarray of shape (n_frames,)
        Our column names, both sides, within :data:`MOTION_RANGES`.
    """
    rng = np.random.default_rng(rng)
    phase = np.linspace(0.0, 2 * np.pi, n_frames)
    out = {}
    for side in ("l", "r"):
        for name, (lo, hi) in MOTION_RANGES.items():
            a = rng.uniform(0, 2 * np.pi)
            out[f"{side}_{name}"] = lo + (hi - lo) * (0.5 + 0.5 * np.sin(phase + a))
    return out


def random_rotation(rng: np.random.Generator, max_tilt_deg: float = 20.0) -> np.ndarray:
    """A body orientation: any heading, tilted up to ``max_tilt_deg``, world z up."""
    from scipy.spatial.transform import Rotation

    yaw, tilt_x, tilt_y = rng.uniform(-180, 180), *rng.uniform(-max_tilt_deg, max_tilt_deg, 2)
    # body axes (X anterior, Y superior, Z right) standing in the world (z up): X = world x, Y = world z
    stand = np.array([[1.0, 0, 0], [0, 0, -1], [0, 1, 0]])      # columns X, Y, Z in world
    return Rotation.from_euler("zxy", [yaw, tilt_x, tilt_y], degrees=True).as_matrix() @ stand


def posed_points(values: dict, n_frames: int, *, body: np.ndarray | None = None, origin=(0.0, 0.0, 1.0),
                 lateral_markers: bool = False) -> dict:
    """Landmarks (T, 3) of a person whose joints take the given angles.

    Parameters
    ----------
    values : dict of str to ndarray of shape (T,) or float
        Angles in degrees under our names; absent ones are 0.
    n_frames : int
    body : ndarray of shape (3, 3), optional
        Pelvis and thorax orientation in the world (columns X, Y, Z); default upright facing +x.
    origin : (3,)
        Mid-hip point, metres.
    lateral_markers : bool
        Add ``<side>_knee_lateral`` and ``<side>_ankle_lateral`` on the thigh's and shank's lateral axes.
    """
    T = n_frames
    vals = {k: np.broadcast_to(np.asarray(v, float), (T,)) for k, v in values.items()}
    B = np.broadcast_to(np.array([[1.0, 0, 0], [0, 0, -1], [0, 1, 0]]) if body is None else body, (T, 3, 3))
    o = np.broadcast_to(np.asarray(origin, float), (T, 3))
    L = LENGTHS
    p = {"neck": o + L["trunk"] * B[..., 1]}
    for side, s in (("l", -1.0), ("r", 1.0)):
        hip = o + s * L["pelvis_half"] * B[..., 2]
        thigh = B @ _relative("hip", side, vals, T)
        knee = hip - L["thigh"] * thigh[..., 1]
        shank = thigh @ _relative("knee", side, vals, T)
        ankle = knee - L["shank"] * shank[..., 1]
        foot = shank @ _relative("ankle", side, vals, T)
        toe = ankle + L["foot"] * foot[..., 0]
        shoulder = p["neck"] + s * L["shoulder_half"] * B[..., 2]
        upper = B @ _relative("shoulder", side, vals, T)
        elbow = shoulder - L["upper_arm"] * upper[..., 1]
        fore = upper @ _relative("elbow", side, vals, T)
        wrist = elbow - L["forearm"] * fore[..., 1]
        p.update({f"{side}_hip": hip, f"{side}_knee": knee, f"{side}_ankle": ankle, f"{side}_toe": toe,
                  f"{side}_shoulder": shoulder, f"{side}_elbow": elbow, f"{side}_wrist": wrist})
        if lateral_markers:
            p[f"{side}_knee_lateral"] = knee + s * LATERAL_MARKER_M * thigh[..., 2]
            p[f"{side}_ankle_lateral"] = ankle + s * LATERAL_MARKER_M * shank[..., 2]
    p["head"] = p["neck"] + 0.2 * B[..., 1]
    return p
