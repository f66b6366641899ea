"""Mappings from other keypoint conventions to the 14-joint skeleton.

Each source format has its keypoint names in order (:data:`KEYPOINTS`) and,
for every joint of :data:`~toolkit.skeleton.JOINTS_14`, a list of
*alternatives* (:data:`MAPPINGS`): each alternative is a set of source
keypoints with weights summing to 1.  :func:`to_skeleton14` uses, per joint
and per frame, the first alternative whose keypoints are all present, so a
head is the mean of the ears, or of the eyes when an ear is missing, and so
on.  A joint with no complete alternative is NaN.

Sources of the keypoint orders: the OpenPose output documentation (BODY_25,
COCO-18), the OpenPose experimental-models list for BODY_25B (its ids 0-16 are
COCO's, 17 UpperNeck, 18 HeadTop, 19-24 the feet; Pose2Sim's demo
``Config.toml`` lists the same ids under the names Neck and Head), the COCO
keypoint task (17 keypoints), the HALPE full-body dataset (26 keypoints, as
AlphaPose, RTMPose and Pose2Sim order them), COCO-WholeBody (133: COCO's 17,
six foot, 68 face and 2 x 21 hand keypoints), MediaPipe Pose's 33 landmarks, and the CMU motion-capture BVH conversions
(31 joints in file order, then their 7 ``End Site`` points named
``<parent>_end``, as returned by ``BvhMotion.positions(end_sites=True)``).

Conventions that differ from ours (documented, not corrected): the OpenPose
BODY_25 and COCO "neck" is the shoulder midpoint, about 0.04 x stature below
our neck (C7); 2D detectors' hips are close to the hip joint centres.
"""

from __future__ import annotations

import numpy as np

from toolkit.errors import InputError
from toolkit.skeleton.skeleton import JOINTS_14

__all__ = ["KEYPOINTS", "MAPPINGS", "FORMATS", "from_skeleton14", "BODY_25", "BODY_25B", "COCO_17", "COCO_18", "HALPE_26",
           "COCO_133", "BLAZEPOSE_33", "CMU_BVH", "CMU_BVH_TO_14", "SKELETON14_BVH_TO_14", "DETECTOR_FORMATS",
           "POSE2SIM_MARKERS", "to_skeleton14", "mapping_table"]

#: OpenPose BODY_25 keypoints, in output order.
BODY_25 = ("Nose", "Neck", "RShoulder", "RElbow", "RWrist", "LShoulder", "LElbow", "LWrist",
           "MidHip", "RHip", "RKnee", "RAnkle", "LHip", "LKnee", "LAnkle", "REye", "LEye", "REar",
           "LEar", "LBigToe", "LSmallToe", "LHeel", "RBigToe", "RSmallToe", "RHeel")

#: COCO-17 keypoints (also AlphaPose, MMPose, Detectron, YOLO pose), in order.
COCO_17 = ("nose", "left_eye", "right_eye", "left_ear", "right_ear", "left_shoulder", "right_shoulder",
           "left_elbow", "right_elbow", "left_wrist", "right_wrist", "left_hip", "right_hip",
           "left_knee", "right_knee", "left_ankle", "right_ankle")

#: OpenPose BODY_25B (experimental) keypoints, in output order.
BODY_25B = ("Nose", "LEye", "REye", "LEar", "REar", "LShoulder", "RShoulder", "LElbow", "RElbow",
            "LWrist", "RWrist", "LHip", "RHip", "LKnee", "RKnee", "LAnkle", "RAnkle", "UpperNeck",
            "HeadTop", "LBigToe", "LSmallToe", "LHeel", "RBigToe", "RSmallToe", "RHeel")

#: OpenPose COCO (18 keypoints, ``--model_pose COCO``), in output order.
COCO_18 = ("Nose", "Neck", "RShoulder", "RElbow", "RWrist", "LShoulder", "LElbow", "LWrist", "RHip", "RKnee",
           "RAnkle", "LHip", "LKnee", "LAnkle", "REye", "LEye", "REar", "LEar")

#: HALPE-26 keypoints (AlphaPose, RTMPose ``body26``, Pose2Sim's ``HALPE_26`` / ``Body_with_feet``), in order.
HALPE_26 = ("Nose", "LEye", "REye", "LEar", "REar", "LShoulder", "RShoulder", "LElbow", "RElbow", "LWrist",
            "RWrist", "LHip", "RHip", "LKnee", "RKnee", "LAnkle", "RAnkle", "Head", "Neck", "Hip", "LBigToe",
            "RBigToe", "LSmallToe", "RSmallToe", "LHeel", "RHeel")

#: COCO-WholeBody (133 keypoints: COCO-17, 6 foot, 68 face, 2 x 21 hand), in order.
COCO_133 = COCO_17 + ("left_big_toe", "left_small_toe", "left_heel", "right_big_toe", "right_small_toe",
                      "right_heel") + tuple(f"face_{i}" for i in range(68)) \
    + tuple(f"left_hand_{i}" for i in range(21)) + tuple(f"right_hand_{i}" for i in range(21))

#: MediaPipe Pose (BlazePose) landmarks, in order (Pose2Sim's ``BLAZEPOSE``).
BLAZEPOSE_33 = ("nose", "left_eye_inner", "left_eye", "left_eye_outer", "right_eye_inner", "right_eye",
                "right_eye_outer", "left_ear", "right_ear", "mouth_left", "mouth_right", "left_shoulder",
                "right_shoulder", "left_elbow", "right_elbow", "left_wrist", "right_wrist", "left_pinky",
                "right_pinky", "left_index", "right_index", "left_thumb", "right_thumb", "left_hip", "right_hip",
                "left_knee", "right_knee", "left_ankle", "right_ankle", "left_heel", "right_heel",
                "left_foot_index", "right_foot_index")

#: Joints of the CMU motion-capture BVH conversions (e.g. ``01_01.bvh``), file
#: order, then the end sites.
CMU_BVH = ("Hips", "LHipJoint", "LeftUpLeg", "LeftLeg", "LeftFoot", "LeftToeBase", "RHipJoint",
           "RightUpLeg", "RightLeg", "RightFoot", "RightToeBase", "LowerBack", "Spine", "Spine1",
           "Neck", "Neck1", "Head", "LeftShoulder", "LeftArm", "LeftForeArm", "LeftHand",
           "LeftFingerBase", "LFingers", "LThumb", "RightShoulder", "RightArm", "RightForeArm",
           "RightHand", "RightFingerBase", "RFingers", "RThumb",
           "LeftToeBase_end", "RightToeBase_end", "Head_end", "LFingers_end", "LThumb_end",
           "RFingers_end", "RThumb_end")

KEYPOINTS = {"body_25": BODY_25, "body_25b": BODY_25B, "coco_17": COCO_17, "cmu_bvh": CMU_BVH,
             "coco_18": COCO_18, "halpe_26": HALPE_26, "coco_133": COCO_133, "blazepose_33": BLAZEPOSE_33}
FORMATS = tuple(KEYPOINTS)
#: The formats of 2D keypoint detectors (all of :data:`FORMATS` but the motion-capture skeleton).
DETECTOR_FORMATS = ("body_25", "body_25b", "coco_18", "coco_17", "halpe_26", "coco_133", "blazepose_33")

#: Our 14 joints under Pose2Sim's marker names (its BODY_25B / HALPE_26 skeletons), in the order Pose2Sim
#: writes them in its .trc files.  Pose2Sim's ``Neck`` and ``Head`` are the detector's neck and head-top
#: keypoints; ours are the base of the neck (C7) and the head centre (docs/conventions.md).
POSE2SIM_MARKERS = {"r_hip": "RHip", "r_knee": "RKnee", "r_ankle": "RAnkle", "l_hip": "LHip", "l_knee": "LKnee",
                    "l_ankle": "LAnkle", "neck": "Neck", "head": "Head", "r_shoulder": "RShoulder",
                    "r_elbow": "RElbow", "r_wrist": "RWrist", "l_shoulder": "LShoulder", "l_elbow": "LElbow",
                    "l_wrist": "LWrist"}


def _one(name):
    return ({name: 1.0},)


def _mean(*names):
    return {n: 1.0 / len(names) for n in names}


def _limbs(fmt_names: dict) -> dict:
    """Direct one-to-one limb joints from {our suffix: (left source, right source)}."""
    out = {}
    for ours, (left, right) in fmt_names.items():
        out["l_" + ours] = _one(left)
        out["r_" + ours] = _one(right)
    return out


_OPENPOSE_LIMBS = {"shoulder": ("LShoulder", "RShoulder"), "elbow": ("LElbow", "RElbow"),
                   "wrist": ("LWrist", "RWrist"), "hip": ("LHip", "RHip"),
                   "knee": ("LKnee", "RKnee"), "ankle": ("LAnkle", "RAnkle")}
_OPENPOSE_HEAD = (_mean("LEar", "REar"), _mean("LEye", "REye"), {"LEar": 1.0}, {"REar": 1.0},
                  {"Nose": 1.0})

#: Per format: joint of JOINTS_14 -> tuple of alternatives ({source name: weight}), first complete wins.
MAPPINGS = {
    "body_25": {
        "head": _OPENPOSE_HEAD,
        "neck": ({"Neck": 1.0}, _mean("LShoulder", "RShoulder")),
        **_limbs(_OPENPOSE_LIMBS),
    },
    "body_25b": {
        "head": _OPENPOSE_HEAD[:2] + (_mean("HeadTop", "UpperNeck"),) + _OPENPOSE_HEAD[2:],
        "neck": ({"UpperNeck": 1.0}, _mean("LShoulder", "RShoulder")),
        **_limbs(_OPENPOSE_LIMBS),
    },
    "coco_17": {
        "head": (_mean("left_ear", "right_ear"), _mean("left_eye", "right_eye"), {"left_ear": 1.0},
                 {"right_ear": 1.0}, {"nose": 1.0}),
        "neck": (_mean("left_shoulder", "right_shoulder"),),
        **_limbs({"shoulder": ("left_shoulder", "right_shoulder"), "elbow": ("left_elbow", "right_elbow"),
                  "wrist": ("left_wrist", "right_wrist"), "hip": ("left_hip", "right_hip"),
                  "knee": ("left_knee", "right_knee"), "ankle": ("left_ankle", "right_ankle")}),
    },
    "coco_18": {
        "head": _OPENPOSE_HEAD,
        "neck": ({"Neck": 1.0}, _mean("LShoulder", "RShoulder")),
        **_limbs(_OPENPOSE_LIMBS),
    },
    "halpe_26": {
        "head": _OPENPOSE_HEAD[:2] + (_mean("Head", "Neck"),) + _OPENPOSE_HEAD[2:],
        "neck": ({"Neck": 1.0}, _mean("LShoulder", "RShoulder")),
        **_limbs(_OPENPOSE_LIMBS),
    },
    "cmu_bvh": {
        # CMU "Head" sits where the neck-to-head distance matches the ANSUR
        # neck-to-head-centre length (about 0.1 m); Neck1 is just above the
        # shoulders, like C7.
        "head": _one("Head"),
        "neck": _one("Neck1"),
        **_limbs({"shoulder": ("LeftArm", "RightArm"), "elbow": ("LeftForeArm", "RightForeArm"),
                  "wrist": ("LeftHand", "RightHand"), "hip": ("LeftUpLeg", "RightUpLeg"),
                  "knee": ("LeftLeg", "RightLeg"), "ankle": ("LeftFoot", "RightFoot")}),
    },
}

MAPPINGS["coco_133"] = MAPPINGS["coco_17"]
MAPPINGS["blazepose_33"] = MAPPINGS["coco_17"]   # the same names for the ears, eyes, nose and limbs

#: CMU BVH names -> 14 joints, as single weight sets (for ``bvh_to_skeleton14``).
CMU_BVH_TO_14 = {j: dict(MAPPINGS["cmu_bvh"][j][0]) for j in JOINTS_14}
#: Names written by ``write_bvh`` -> 14 joints (identity).
SKELETON14_BVH_TO_14 = {j: {j: 1.0} for j in JOINTS_14}


def to_skeleton14(keypoints: np.ndarray, fmt: str, confidence: bool = False,
                  min_confidence: float = 0.0) -> np.ndarray:
    """Map keypoints of another convention to the 14-joint skeleton.

    Parameters
    ----------
    keypoints : ndarray of shape (..., K, D)
        ``K = len(KEYPOINTS[fmt])``.  Coordinates in any unit; NaN marks a
        missing keypoint.  With ``confidence=True`` the last channel is a
        detection confidence (OpenPose ``(x, y, c)``).
    fmt : str
        One of :data:`FORMATS`.
    confidence : bool
        Whether the last channel is a confidence.
    min_confidence : float
        With ``confidence``, a keypoint whose confidence is ``<= min_confidence``
        is missing (OpenPose writes ``c = 0`` for undetected keypoints).

    Returns
    -------
    ndarray of shape (..., 14, D)
        Joints in the order of ``JOINTS_14``; each is the weighted mean of the
        first complete alternative of :data:`MAPPINGS`, NaN when none is
        complete.  With ``confidence``, the output confidence is the smallest
        confidence of the keypoints used (0 where the joint is missing, with
        NaN coordinates).

    Raises
    ------
    InputError
        Unknown format or a keypoint array of the wrong shape.
    """
    if fmt not in KEYPOINTS:
        raise InputError("fmt", f"one of {list(FORMATS)}", repr(fmt))
    names = KEYPOINTS[fmt]
    k = np.asarray(keypoints, float)
    if k.ndim < 2 or k.shape[-2] != len(names) or k.shape[-1] < (2 if confidence else 1):
        exp = f"(..., {len(names)}, {'3' if confidence else 'D'})"
        raise InputError("keypoints", f"an array of shape {exp} for {fmt}", f"shape {k.shape}")
    if confidence:
        coords, conf = k[..., :-1], k[..., -1]
        present = (conf > min_confidence) & np.all(np.isfinite(coords), -1)
    else:
        coords, conf = k, None
        present = np.all(np.isfinite(coords), -1)
    index = {n: i for i, n in enumerate(names)}
    out = np.full(k.shape[:-2] + (14, coords.shape[-1]), np.nan)
    out_c = np.zeros(k.shape[:-2] + (14,))
    for j, jn in enumerate(JOINTS_14):
        done = np.zeros(k.shape[:-2], bool)
        for alt in MAPPINGS[fmt][jn]:
            idx = [index[n] for n in alt]
            w = np.array([alt[n] for n in alt])
            ok = np.all(present[..., idx], -1) & ~done
            if np.any(ok):
                val = np.einsum("...kd,k->...d", np.where(present[..., idx, None], coords[..., idx, :], 0.0), w)
                out[..., j, :] = np.where(ok[..., None], val, out[..., j, :])
                if conf is not None:
                    out_c[..., j] = np.where(ok, np.min(np.where(present[..., idx], conf[..., idx], np.inf), -1),
                                             out_c[..., j])
            done |= ok
    if confidence:
        return np.concatenate([out, out_c[..., None]], -1)
    return out


def from_skeleton14(joints: np.ndarray, fmt: str = "body_25", confidence: np.ndarray | float = 1.0) -> np.ndarray:
    """Keypoints of a detector convention carrying 14 joints (the inverse of :func:`to_skeleton14`).

    Each joint is written to the keypoints of the first alternative of :data:`MAPPINGS`
    (e.g. BODY_25 ``head`` to both ears, ``neck`` to ``Neck``), so that
    ``to_skeleton14(from_skeleton14(j, fmt), fmt)`` gives ``j`` back; the other keypoints are
    missing (NaN, confidence 0).  For writing synthetic detections or exporting poses to
    tools that read OpenPose files.

    Parameters
    ----------
    joints : ndarray of shape (..., 14, D)
        Joints in the order of ``JOINTS_14``; NaN = missing.
    fmt : str
        One of :data:`FORMATS`.
    confidence : float or ndarray of shape (..., 14)
        Confidence written for each present joint.

    Returns
    -------
    ndarray of shape (..., K, D + 1)
        Coordinates and confidence (0 where missing).

    Raises
    ------
    InputError
        Unknown format or joints of the wrong shape.
    """
    if fmt not in KEYPOINTS:
        raise InputError("fmt", f"one of {list(FORMATS)}", repr(fmt))
    j = np.asarray(joints, float)
    if j.ndim < 2 or j.shape[-2] != 14:
        raise InputError("joints", "an array of shape (..., 14, D)", f"shape {j.shape}")
    names = KEYPOINTS[fmt]
    index = {n: i for i, n in enumerate(names)}
    conf = np.broadcast_to(np.asarray(confidence, float), j.shape[:-1])
    out = np.full(j.shape[:-2] + (len(names), j.shape[-1] + 1), np.nan)
    out[..., -1] = 0.0
    for k, jn in enumerate(JOINTS_14):
        present = np.all(np.isfinite(j[..., k, :]), -1)
        for n in MAPPINGS[fmt][jn][0]:
            out[..., index[n], :-1] = j[..., k, :]
            out[..., index[n], -1] = np.where(present, conf[..., k], 0.0)
    return out


def mapping_table(fmt: str) -> str:
    """The mapping of ``fmt`` as a Markdown table (used in ``docs/motion.md``)."""
    if fmt not in MAPPINGS:
        raise InputError("fmt", f"one of {list(FORMATS)}", repr(fmt))
    rows = ["| joint | source keypoints (first complete alternative wins) |", "|---|---|"]
    for jn in JOINTS_14:
        alts = []
        for alt in MAPPINGS[fmt][jn]:
            if len(alt) == 1:
                alts.append(next(iter(alt)))
            else:
                alts.append("mean(" + ", ".join(alt) + ")")
        rows.append(f"| {jn} | " + " → ".join(alts) + " |")
    return "\n".join(rows)
