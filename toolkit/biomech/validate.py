"""Comparing joint angles with Plug-in Gait's, as Vicon stores them in a C3D file.

Vicon writes Plug-in Gait's model outputs into the C3D's POINT section as
3-vectors named ``LHipAngles``, ``RKneeAngles`` ... in degrees (components:
flexion, ab/adduction, rotation; for the ankle dorsiflexion first).  A C3D
reader that scales points by ``POINT:UNITS`` (``mm`` -> metres, as
:func:`toolkit.io.c3d.read_c3d` does) scales these too: pass ``scale=1000``.
"""

from __future__ import annotations

import numpy as np

from toolkit.biomech.angles import JointAngles, angle_rms
from toolkit.errors import InputError

#: Our angle (without the side) -> (Plug-in Gait output without the side, component).
PLUGIN_GAIT_OUTPUTS = {
    "hip_flexion": ("HipAngles", 0), "hip_adduction": ("HipAngles", 1), "hip_rotation": ("HipAngles", 2),
    "knee_flexion": ("KneeAngles", 0), "knee_adduction": ("KneeAngles", 1), "knee_rotation": ("KneeAngles", 2),
    "ankle_dorsiflexion": ("AnkleAngles", 0),
    "shoulder_flexion": ("ShoulderAngles", 0), "shoulder_abduction": ("ShoulderAngles", 1),
    "shoulder_rotation": ("ShoulderAngles", 2), "elbow_flexion": ("ElbowAngles", 0),
}


def plugin_gait_angles(labels, positions: np.ndarray, *, scale: float = 1.0) -> dict:
    """Plug-in Gait's angles from a C3D's points, under our column names.

    Parameters
    ----------
    labels : sequence of str
        M point labels.
    positions : ndarray of shape (T, M, 3)
        The points as read; angles are ``positions * scale`` degrees.
    scale : float
        1000 when the reader turned millimetres into metres.

    Returns
    -------
    dict of str to ndarray of shape (T,)
        ``l_knee_flexion`` ... for every output present.
    """
    labels = [str(x) for x in labels]
    p = np.asarray(positions, float)
    if p.ndim != 3 or p.shape[1:] != (len(labels), 3):
        raise InputError("positions", f"an array of shape (T, {len(labels)}, 3)", f"shape {p.shape}")
    out = {}
    for side, prefix in (("l", "L"), ("r", "R")):
        for ours, (name, k) in PLUGIN_GAIT_OUTPUTS.items():
            if prefix + name in labels:
                out[f"{side}_{ours}"] = p[:, labels.index(prefix + name), k] * scale
    return out


def compare_angles(angles: JointAngles, reference: dict) -> dict:
    """RMS and bias of each angle against a reference with the same column names.

    Returns
    -------
    dict of str to dict
        ``{name: {"rms_deg", "bias_deg", "n_frames"}}`` for the names in both.
    """
    out = {}
    for name in angles.names:
        if name in reference:
            rms, bias, n = angle_rms(angles[name], reference[name])
            out[name] = {"rms_deg": rms, "bias_deg": bias, "n_frames": n}
    return out


#: Landmarks a markerless system could give: the joint centres and the feet's toe and heel points.
CENTRES_ONLY = ("head", "neck", "l_shoulder", "l_elbow", "l_wrist", "r_shoulder", "r_elbow", "r_wrist", "l_hip",
                "l_knee", "l_ankle", "r_hip", "r_knee", "r_ankle", "l_toe", "r_toe", "l_heel", "r_heel")


def c3d_landmarks(path) -> tuple[dict, float, dict]:
    """Landmarks of a labelled C3D: joint centres by the project's marker system, plus its markers.

    Parameters
    ----------
    path : path
        A labelled C3D file (Plug-in Gait or ISB-style names).

    Returns
    -------
    points : dict of str to ndarray of shape (T, 3)
    fps : float
    reference : dict of str to ndarray of shape (T,)
        Plug-in Gait's angles stored in the file (empty when it has none).
    """
    from toolkit.biomech.mapping import joints_to_points, marker_points
    from toolkit.markers.functional import joint_centres, trajectories_from_c3d

    tr = trajectories_from_c3d(path)
    res = joint_centres(tr)
    points = joints_to_points(res.joints, res.names)
    for k, v in marker_points(tr.labels, tr.positions).items():
        points.setdefault(k, v)
    return points, float(tr.fps), plugin_gait_angles(tr.labels, tr.positions, scale=1000.0)


def plugin_gait_comparison(movement, static=None, *, engines=("own",), out=None) -> dict:
    """Our angles against Plug-in Gait's on a C3D walk, per engine and landmark set.

    Parameters
    ----------
    movement : path
        The C3D trial with Plug-in Gait's outputs.
    static : path, optional
        The static trial of the same person (the feet's pitch offsets).
    engines : tuple of {"own", "opensim"}
    out : path, optional
        Folder for OpenSim's files (required with ``"opensim"``).

    Returns
    -------
    dict
        ``{variant: {angle: {"rms_deg", "bias_deg", "n_frames"}}}``; variants
        ``own/markers`` (joint centres and every mapped marker), ``own/centres``
        (joint centres, toe and heel only), ``opensim/markers``.
    """
    from toolkit.biomech.angles import joint_angles

    points, fps, reference = c3d_landmarks(movement)
    if not reference:
        raise InputError(str(movement), "Plug-in Gait angles (LKneeAngles ...) among the points", "none")
    static_points = c3d_landmarks(static)[0] if static is not None else None
    out_dict = {}
    if "own" in engines:
        out_dict["own/markers"] = compare_angles(joint_angles(points, fps, static=static_points), reference)
        centres = {k: v for k, v in points.items() if k in CENTRES_ONLY}
        static_c = {k: v for k, v in static_points.items() if k in CENTRES_ONLY} if static_points else None
        out_dict["own/centres"] = compare_angles(joint_angles(centres, fps, static=static_c), reference)
    if "opensim" in engines:
        from toolkit.biomech.opensim_model import opensim_angles

        if out is None:
            raise InputError("out", "a folder for OpenSim's files", "None")
        res = opensim_angles(points, fps, out, static=static_points)
        out_dict["opensim/markers"] = compare_angles(res.angles, reference)
        out_dict["opensim/residual_mm"] = {"all": {"rms_mm": float(np.sqrt(np.nanmean(np.concatenate(
            [r for r in res.residuals_m.values()]) ** 2)) * 1e3)}}
    return out_dict
