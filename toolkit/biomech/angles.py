"""Joint angles from segment frames, named and signed as Plug-in Gait reports them.

Each angle is a Cardan decomposition of the distal segment's frame in the
proximal one's (:mod:`toolkit.biomech.segments`: X anterior, Y superior, Z
right), in the order Z-X-Y: flexion about the proximal segment's lateral
axis first, then ab/adduction about the floating anterior axis, then
rotation about the distal segment's own long axis.  This is the joint
coordinate system of Grood and Suntay (1983, *J Biomech Eng* 105:136-144)
adopted by the ISB (Wu et al. 2002) and by Vicon's Plug-in Gait (which uses
the same Y-X-Z order in its own axis names).

Signs follow Plug-in Gait for both sides: hip, knee, shoulder and elbow
flexion positive; ankle dorsiflexion positive; hip adduction, shoulder
abduction and internal rotation positive.  Column names are
``<side>_<joint>_<motion>`` (``l_knee_flexion``, ``r_ankle_dorsiflexion``).

What the joints of a 14-joint skeleton leave undetermined is not reported:
knee and elbow ab/adduction and rotation (a hinge from three joint centres
has none), the ankle without a toe point.  Hip and shoulder rotation come
from the plane of the bent knee or elbow (:mod:`toolkit.biomech.segments`)
and read 0 when the limb is straight.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from toolkit.biomech.segments import foot_pitch_offsets, segment_frames
from toolkit.errors import InputError

#: (joint, proximal segment, distal segment, ((motion, Cardan index, sign right, sign left), ...)).
#: Cardan indices: 0 = about Z (flexion), 1 = about X (ab/adduction), 2 = about Y (rotation).
ANGLE_DEFINITIONS = (
    ("hip", "pelvis", "thigh", (("flexion", 0, 1, 1), ("adduction", 1, 1, -1), ("rotation", 2, 1, -1))),
    ("knee", "thigh", "shank", (("flexion", 0, -1, -1),)),
    ("ankle", "shank", "foot", (("dorsiflexion", 0, 1, 1),)),
    ("shoulder", "thorax", "upper_arm", (("flexion", 0, 1, 1), ("abduction", 1, -1, 1), ("rotation", 2, 1, -1))),
    ("elbow", "upper_arm", "forearm", (("flexion", 0, 1, 1),)),
)


def cardan_zxy(R: np.ndarray) -> np.ndarray:
    """Angles (a, b, c) in degrees with ``R = Rz(a) @ Rx(b) @ Ry(c)``.

    Parameters
    ----------
    R : ndarray of shape (..., 3, 3)
        Rotation matrices; NaN entries give NaN angles.

    Returns
    -------
    ndarray of shape (..., 3)
        Degrees; ``b`` in [-90, 90].
    """
    R = np.asarray(R, float)
    b = np.arcsin(np.clip(R[..., 2, 1], -1.0, 1.0))
    a = np.arctan2(-R[..., 0, 1], R[..., 1, 1])
    c = np.arctan2(-R[..., 2, 0], R[..., 2, 2])
    return np.rad2deg(np.stack([a, b, c], -1))


def rotation_zxy(angles_deg: np.ndarray) -> np.ndarray:
    """The inverse of :func:`cardan_zxy`: ``Rz(a) @ Rx(b) @ Ry(c)`` (..., 3, 3) from degrees (..., 3)."""
    a, b, c = np.moveaxis(np.deg2rad(np.asarray(angles_deg, float)), -1, 0)
    z, o = np.zeros_like(a), np.ones_like(a)
    Rz = np.stack([np.stack([np.cos(a), -np.sin(a), z], -1), np.stack([np.sin(a), np.cos(a), z], -1),
                   np.stack([z, z, o], -1)], -2)
    Rx = np.stack([np.stack([o, z, z], -1), np.stack([z, np.cos(b), -np.sin(b)], -1),
                   np.stack([z, np.sin(b), np.cos(b)], -1)], -2)
    Ry = np.stack([np.stack([np.cos(c), z, np.sin(c)], -1), np.stack([z, o, z], -1),
                   np.stack([-np.sin(c), z, np.cos(c)], -1)], -2)
    return Rz @ Rx @ Ry


@dataclass(frozen=True)
class JointAngles:
    """Joint angles over time.

    Attributes
    ----------
    time : ndarray of shape (T,)
        Seconds from the first frame.
    names : tuple of str
        One per column, ``<side>_<joint>_<motion>``.
    degrees : ndarray of shape (T, K)
        Degrees, NaN where a segment is missing.
    engine : str
        ``"own"`` or ``"opensim"``.
    """

    time: np.ndarray
    names: tuple
    degrees: np.ndarray
    engine: str = "own"

    def __getitem__(self, name: str) -> np.ndarray:
        """The column ``name`` (T,)."""
        if name not in self.names:
            raise KeyError(f"no angle {name!r}; angles are {self.names}")
        return self.degrees[:, self.names.index(name)]


def joint_angles(points: dict, fps: float, *, static: dict | None = None, engine: str = "own") -> JointAngles:
    """The project's own joint angles from named 3D points.

    Parameters
    ----------
    points : dict of str to ndarray of shape (T, 3)
        Metres, world frame, NaN = missing (see :func:`~toolkit.biomech.segments.segment_frames`).
    fps : float
        Frames per second (for the time column).
    static : dict of str to ndarray of shape (S, 3), optional
        Landmarks of a static trial of the same person: the feet's pitch
        offsets are measured there (:func:`~toolkit.biomech.segments.foot_pitch_offsets`).
    engine : str
        Recorded in the result.

    Returns
    -------
    JointAngles
        Every angle whose two segments could be built, in the order of
        :data:`ANGLE_DEFINITIONS`, left side first.

    Raises
    ------
    InputError
        Bad ``fps``; points missing the hips or the trunk (from :func:`segment_frames`).
    """
    if not (np.isfinite(fps) and fps > 0):
        raise InputError("fps", "a positive frame rate", repr(fps))
    offsets = foot_pitch_offsets(static) if static is not None else None
    frames = segment_frames(points, foot_offsets=offsets)
    n = len(frames["pelvis"])
    names, cols = [], []
    for side in ("l", "r"):
        for joint, prox, dist, motions in ANGLE_DEFINITIONS:
            prox_key = prox if prox in ("pelvis", "thorax") else f"{side}_{prox}"
            dist_key = f"{side}_{dist}"
            if prox_key not in frames or dist_key not in frames:
                continue
            rel = np.einsum("tji,tjk->tik", frames[prox_key], frames[dist_key])
            cardan = cardan_zxy(rel)
            for motion, idx, sign_r, sign_l in motions:
                names.append(f"{side}_{joint}_{motion}")
                cols.append(cardan[:, idx] * (sign_r if side == "r" else sign_l))
    degrees = np.stack(cols, -1) if cols else np.zeros((n, 0))
    return JointAngles(time=np.arange(n) / float(fps), names=tuple(names), degrees=degrees, engine=engine)


def angle_rms(estimate: np.ndarray, reference: np.ndarray) -> tuple[float, float, int]:
    """RMS and mean (bias) of ``estimate - reference`` over frames where both are finite.

    Parameters
    ----------
    estimate, reference : ndarray of shape (T,)
        Degrees.

    Returns
    -------
    rms_deg, bias_deg : float
        NaN when no frame has both.
    n_frames : int
    """
    e, r = np.asarray(estimate, float), np.asarray(reference, float)
    if e.shape != r.shape:
        raise InputError("reference", f"an array of shape {e.shape}", f"shape {r.shape}")
    ok = np.isfinite(e) & np.isfinite(r)
    if not ok.any():
        return float("nan"), float("nan"), 0
    d = e[ok] - r[ok]
    return float(np.sqrt(np.mean(d ** 2))), float(np.mean(d)), int(ok.sum())
