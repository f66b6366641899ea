"""Which point of each system's output is which landmark of the joint-angle and OpenSim models.

The landmarks are named as in :mod:`toolkit.biomech.segments` (``l_hip``,
``r_knee``, ``l_toe``, ``r_asis`` ...); the OpenSim model of
:mod:`toolkit.biomech.opensim_model` carries one marker per joint landmark
under the same name, so the same table serves both engines.

=================  ============================  ==========================================
system             output                        joints -> landmarks
=================  ============================  ==========================================
keypoints          ``poses3d.npz`` (14 joints)   same names (:data:`SKELETON_14`)
free viewpoint     ``poses3d.npz`` (14 joints)   same names
soft body          ``joints.npz`` (14 joints)    same names
depth              ``skeleton.npz`` (13 joints)  ``l_hand`` -> ``l_wrist``, ``l_foot`` ->
                                                 ``l_ankle``; ``neck`` = mid-shoulder
markers            ``joint_centres.npz``         same names; from ``trajectories.npz`` the
                   (14 joints)                   markers of :data:`MARKER_LANDMARKS`
=================  ============================  ==========================================
"""

from __future__ import annotations

import numpy as np

from toolkit.errors import InputError
from toolkit.skeleton import JOINTS_13, JOINTS_14

#: Joint name of a system's skeleton -> landmark name (names not listed map to themselves).
SYSTEM_JOINTS = {
    "skeleton14": {},
    "depth13": {"l_hand": "l_wrist", "r_hand": "r_wrist", "l_foot": "l_ankle", "r_foot": "r_ankle"},
}

#: Landmark -> marker labels that give it (first found wins): Plug-in Gait names, then ISB-style ones.
MARKER_LANDMARKS = {
    "l_asis": ("LASI", "LASIS"), "r_asis": ("RASI", "RASIS"),
    "l_psis": ("LPSI", "LPSIS"), "r_psis": ("RPSI", "RPSIS"),
    "c7": ("C7",), "t10": ("T10",), "clav": ("CLAV",), "strn": ("STRN",),
    "l_knee_lateral": ("LKNE", "LLFE"), "r_knee_lateral": ("RKNE", "RLFE"),
    "l_ankle_lateral": ("LANK", "LLM"), "r_ankle_lateral": ("RANK", "RLM"),
    "l_toe": ("LTOE", "LMH2", "LTT2"), "r_toe": ("RTOE", "RMH2", "RTT2"),
    "l_heel": ("LHEE", "LCAL"), "r_heel": ("RHEE", "RCAL"),
}


def joints_to_points(joints: np.ndarray, names) -> dict:
    """Landmarks from a system's joints.

    Parameters
    ----------
    joints : ndarray of shape (T, J, 3)
        Metres, world frame, NaN = missing.
    names : sequence of str
        J joint names: the 14 of :data:`toolkit.skeleton.JOINTS_14` or the 13
        of the depth skeleton (:data:`toolkit.skeleton.JOINTS_13`).

    Returns
    -------
    dict of str to ndarray of shape (T, 3)

    Raises
    ------
    InputError
        Another shape or another joint list.
    """
    j = np.asarray(joints, float)
    names = tuple(str(n) for n in names)
    if j.ndim != 3 or j.shape[1:] != (len(names), 3):
        raise InputError("joints", f"an array of shape (T, {len(names)}, 3)", f"shape {j.shape}")
    if names == JOINTS_14:
        rename = SYSTEM_JOINTS["skeleton14"]
    elif names == JOINTS_13:
        rename = SYSTEM_JOINTS["depth13"]
    else:
        raise InputError("names", f"the joints of SKELETON_14 {JOINTS_14} or of the depth skeleton {JOINTS_13}",
                         str(names))
    points = {rename.get(n, n): j[:, i] for i, n in enumerate(names)}
    if "neck" not in points:
        points["neck"] = 0.5 * (points["l_shoulder"] + points["r_shoulder"])
    return points


def marker_points(labels, positions: np.ndarray) -> dict:
    """Landmarks taken from labelled markers (:data:`MARKER_LANDMARKS`).

    Parameters
    ----------
    labels : sequence of str
        M marker labels.
    positions : ndarray of shape (T, M, 3)
        Metres.

    Returns
    -------
    dict of str to ndarray of shape (T, 3)
        Only the landmarks one of whose labels is present.
    """
    labels = [str(x) for x in labels]
    p = np.asarray(positions, float)
    if p.ndim != 3 or p.shape[1:] != (len(labels), 3):
        raise InputError("positions", f"an array of shape (T, {len(labels)}, 3)", f"shape {p.shape}")
    out = {}
    for landmark, candidates in MARKER_LANDMARKS.items():
        for c in candidates:
            if c in labels:
                out[landmark] = p[:, labels.index(c)]
                break
    return out


def skeleton14_from_points(points: dict) -> np.ndarray:
    """The 14 joints (T, 14, 3) of :data:`JOINTS_14` from landmarks (``head`` NaN when absent)."""
    missing = [n for n in JOINTS_14 if n not in points and n != "head"]
    if missing:
        raise InputError("points", f"every joint of {JOINTS_14}", f"no {missing}")
    T = len(points["neck"])
    return np.stack([points.get(n, np.full((T, 3), np.nan)) for n in JOINTS_14], 1)
