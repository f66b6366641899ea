"""Forward and inverse kinematics of the 14-joint skeleton.

Angles and frames
-----------------
World frame: metres, z up, ground plane z = 0.  The body frame of a person
with zero yaw has x = the person's right, y = forward, z = up (so the person
faces +y and their left side is at -x, as in
:meth:`~toolkit.anthropometry.proportions.BodyProportions.rest_pose`).

All angles are radians.  With ``Rx, Ry, Rz`` the right-handed rotations about
the body axes:

* pelvis: ``R_pelvis = Rz(yaw) @ Rx(-pitch) @ Ry(roll)``; ``yaw`` turns the
  person counter-clockwise seen from above, ``pitch > 0`` tilts the pelvis
  forward, ``roll > 0`` lowers the right hip.
* trunk: ``R_trunk = R_pelvis @ Rx(-lean) @ Rz(twist)``; ``lean > 0`` bends
  the trunk forward, ``twist > 0`` turns the shoulders counter-clockwise
  relative to the hips.  The trunk pivots about the pelvis centre (mid-hip
  point), so the neck-to-hip distances stay constant; there is no lateral
  trunk bend relative to the pelvis (use ``roll``).
* head: ``R_trunk @ Rx(-head_pitch) @ Ry(head_roll)`` applied to the neck-head
  segment; ``head_pitch > 0`` nods forward, ``head_roll > 0`` tilts to the
  right.
* limbs, per side (left index 0, right 1), with ``s = +1`` left and ``-1``
  right: ``R_limb = R_parent @ Rx(flexion) @ Ry(s * abduction) @ Rz(-s * rotation)``
  acting on the segment's rest direction ``(0, 0, -1)``; flexion > 0 moves the
  limb forward, abduction > 0 away from the body, rotation > 0 is internal
  rotation.  The elbow flexes forward: ``forearm = R_upper @ Rx(+elbow)``; the
  knee flexes backward: ``shank = R_thigh @ Rx(-knee)``.  Elbow and knee
  flexion are >= 0 (they never hyper-extend).

With all angles zero and ``root = (0, 0, ankle_height + shank + thigh)`` the
skeleton is :meth:`BodyProportions.rest_pose`.
"""

from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np

from toolkit.anthropometry.proportions import BodyProportions
from toolkit.errors import InputError
from toolkit.skeleton import SKELETON_14

__all__ = ["KNEE_MIN_FLEXION", "Pose14", "forward_kinematics", "inverse_kinematics",
           "bone_lengths14", "sequence_bone_lengths", "set_bone_lengths", "two_bone_ik", "leg_reach",
           "align_to_ground", "resample", "rot_x", "rot_y", "rot_z", "LEFT", "RIGHT"]

#: Side indices of the per-limb arrays.
LEFT, RIGHT = 0, 1
_SIDE_SIGN = np.array([1.0, -1.0])  # s = +1 left, -1 right

#: Smallest knee flexion (rad) of a planted leg in the motion library: a
#: standing knee is never fully locked, and 4 degrees keeps the leg's
#: bending plane well defined.
KNEE_MIN_FLEXION = np.deg2rad(4.0)

_J = {n: i for i, n in enumerate(SKELETON_14.joint_names)}


# ----------------------------------------------------------------- rotations
def rot_x(a) -> np.ndarray:
    """Rotations about x, shape ``a.shape + (3, 3)``."""
    a = np.asarray(a, float)
    c, s = np.cos(a), np.sin(a)
    o, z = np.ones_like(a), np.zeros_like(a)
    return np.stack([np.stack([o, z, z], -1), np.stack([z, c, -s], -1), np.stack([z, s, c], -1)], -2)


def rot_y(a) -> np.ndarray:
    """Rotations about y, shape ``a.shape + (3, 3)``."""
    a = np.asarray(a, float)
    c, s = np.cos(a), np.sin(a)
    o, z = np.ones_like(a), np.zeros_like(a)
    return np.stack([np.stack([c, z, s], -1), np.stack([z, o, z], -1), np.stack([-s, z, c], -1)], -2)


def rot_z(a) -> np.ndarray:
    """Rotations about z, shape ``a.shape + (3, 3)``."""
    a = np.asarray(a, float)
    c, s = np.cos(a), np.sin(a)
    o, z = np.ones_like(a), np.zeros_like(a)
    return np.stack([np.stack([c, -s, z], -1), np.stack([s, c, z], -1), np.stack([z, z, o], -1)], -2)


def _apply(R, v):
    """``R @ v`` for stacks: R (..., 3, 3), v (..., 3)."""
    return np.einsum("...ij,...j->...i", R, v)


def _unit(v, eps=1e-12):
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    return v / np.maximum(n, eps)


# ---------------------------------------------------------------------- pose
@dataclass(frozen=True)
class Pose14:
    """Joint angles of the 14-joint skeleton over ``n_frames`` frames.

    Attributes
    ----------
    root : ndarray of shape (T, 3)
        Pelvis centre (mid-point of the hip joints), world, metres.
    yaw, pitch, roll : ndarray of shape (T,)
        Pelvis orientation, radians (see the module docstring).
    lean, twist : ndarray of shape (T,)
        Trunk forward bend and axial twist relative to the pelvis, radians.
    head_pitch, head_roll : ndarray of shape (T,)
        Neck-to-head segment relative to the trunk, radians.
    shoulder : ndarray of shape (T, 2, 3)
        Per side (left, right): flexion, abduction, internal rotation, radians.
    elbow : ndarray of shape (T, 2)
        Elbow flexion, radians, >= 0.
    hip : ndarray of shape (T, 2, 3)
        Per side: flexion, abduction, internal rotation, radians.
    knee : ndarray of shape (T, 2)
        Knee flexion, radians, >= 0.
    """

    root: np.ndarray
    yaw: np.ndarray
    pitch: np.ndarray
    roll: np.ndarray
    lean: np.ndarray
    twist: np.ndarray
    head_pitch: np.ndarray
    head_roll: np.ndarray
    shoulder: np.ndarray
    elbow: np.ndarray
    hip: np.ndarray
    knee: np.ndarray

    def __post_init__(self):
        root = np.asarray(self.root, float)
        if root.ndim != 2 or root.shape[1] != 3:
            raise InputError("Pose14.root", "an array of shape (T, 3)", f"shape {root.shape}")
        n = root.shape[0]
        shapes = {"shoulder": (n, 2, 3), "hip": (n, 2, 3), "elbow": (n, 2), "knee": (n, 2)}
        for f in fields(self):
            v = np.asarray(getattr(self, f.name), float)
            if f.name != "root":
                want = shapes.get(f.name, (n,))
                if v.shape != want:
                    raise InputError(f"Pose14.{f.name}", f"an array of shape {want}", f"shape {v.shape}")
            object.__setattr__(self, f.name, v)

    @property
    def n_frames(self) -> int:
        return self.root.shape[0]

    @classmethod
    def neutral(cls, n_frames: int, root=None) -> "Pose14":
        """All angles zero; ``root`` (T, 3) or (3,) defaults to the origin."""
        r = np.zeros((n_frames, 3)) if root is None else np.broadcast_to(np.asarray(root, float),
                                                                          (n_frames, 3)).copy()
        z = np.zeros(n_frames)
        return cls(root=r, yaw=z, pitch=z, roll=z, lean=z, twist=z, head_pitch=z, head_roll=z,
                   shoulder=np.zeros((n_frames, 2, 3)), elbow=np.zeros((n_frames, 2)),
                   hip=np.zeros((n_frames, 2, 3)), knee=np.zeros((n_frames, 2)))

    def pelvis_rotation(self) -> np.ndarray:
        """``R_pelvis`` (T, 3, 3): body axes (right, forward, up) in world coordinates as columns."""
        return rot_z(self.yaw) @ rot_x(-self.pitch) @ rot_y(self.roll)

    def trunk_rotation(self) -> np.ndarray:
        """``R_trunk`` (T, 3, 3)."""
        return self.pelvis_rotation() @ rot_x(-self.lean) @ rot_z(self.twist)


def _limb_rotation(R_parent, angles, side):
    """Parent frame (T,3,3) and (T,3) flexion/abduction/rotation -> segment frame."""
    s = _SIDE_SIGN[side]
    return R_parent @ rot_x(angles[:, 0]) @ rot_y(s * angles[:, 1]) @ rot_z(-s * angles[:, 2])


def forward_kinematics(proportions: BodyProportions, pose: Pose14) -> np.ndarray:
    """Joint positions of the 14-joint skeleton.

    Parameters
    ----------
    proportions : BodyProportions
        Segment lengths, metres.
    pose : Pose14
        Angles over T frames.

    Returns
    -------
    ndarray of shape (T, 14, 3)
        World positions, metres, order of :data:`toolkit.skeleton.JOINTS_14`.
        Bone lengths equal :func:`bone_lengths14` in every frame.
    """
    p = proportions
    n = pose.n_frames
    out = np.empty((n, 14, 3))
    Rp = pose.pelvis_rotation()
    Rt = pose.trunk_rotation()
    root = pose.root
    e = np.zeros((n, 3))

    def vec(x, y, z):
        v = e.copy()
        v[:, 0], v[:, 1], v[:, 2] = x, y, z
        return v

    neck = root + _apply(Rt, vec(0, 0, p.torso))
    out[:, _J["neck"]] = neck
    Rh = Rt @ rot_x(-pose.head_pitch) @ rot_y(pose.head_roll)
    out[:, _J["head"]] = neck + _apply(Rh, vec(0, 0, p.neck_to_head))
    down = vec(0, 0, -1)
    for side, pre in ((LEFT, "l_"), (RIGHT, "r_")):
        lat = -1.0 if side == LEFT else 1.0
        sh = neck + _apply(Rt, vec(lat * p.shoulder_half_width, 0, -p.shoulder_drop))
        Ru = _limb_rotation(Rt, pose.shoulder[:, side], side)
        el = sh + p.upper_arm * _apply(Ru, down)
        wr = el + p.forearm * _apply(Ru @ rot_x(pose.elbow[:, side]), down)
        hp = root + _apply(Rp, vec(lat * p.hip_half_width, 0, 0))
        Rth = _limb_rotation(Rp, pose.hip[:, side], side)
        kn = hp + p.thigh * _apply(Rth, down)
        an = kn + p.shank * _apply(Rth @ rot_x(-pose.knee[:, side]), down)
        for name, val in (("shoulder", sh), ("elbow", el), ("wrist", wr), ("hip", hp), ("knee", kn),
                          ("ankle", an)):
            out[:, _J[pre + name]] = val
    return out


# ------------------------------------------------------------------- inverse
def _limb_angles(R_parent, proximal, mid, distal, side, bend_sign):
    """Invert one limb: flexion/abduction/rotation of the proximal joint and the bend angle.

    ``bend_sign`` is +1 for the elbow (Rx(+e)) and -1 for the knee (Rx(-k)).
    A straight limb has an undefined axial rotation; it is returned as 0.
    """
    s = _SIDE_SIGN[side]
    t = np.einsum("tji,tj->ti", R_parent, _unit(mid - proximal))
    abd = s * np.arcsin(np.clip(-t[:, 0], -1, 1))
    flex = np.arctan2(t[:, 1], -t[:, 2])
    R_fa = R_parent @ rot_x(flex) @ rot_y(s * abd)
    d = np.einsum("tji,tj->ti", R_fa, _unit(distal - mid))
    bend = np.arccos(np.clip(-d[:, 2], -1, 1))
    sb = np.sin(bend)
    rot = np.where(sb > 1e-9, np.arctan2(bend_sign * s * d[:, 0], bend_sign * d[:, 1]), 0.0)
    return np.stack([flex, abd, rot], -1), bend


def inverse_kinematics(joints: np.ndarray) -> Pose14:
    """Angles that reproduce joint positions under :func:`forward_kinematics`.

    Only directions are used, so ``forward_kinematics(p, inverse_kinematics(J))``
    equals ``J`` when ``J`` has the bone lengths of ``p`` and the trunk
    constraint of the model (neck direction perpendicular to the hip axis).
    The pelvis ``pitch`` is not observable from joint positions and is
    returned as 0 (the trunk lean and hip flexions absorb it); the axial
    rotation of a straight limb is returned as 0.

    Parameters
    ----------
    joints : ndarray of shape (T, 14, 3) or (14, 3)
        Metres, world, z up.

    Returns
    -------
    Pose14
    """
    j = SKELETON_14.check_joints(joints)
    if j.ndim == 2:
        j = j[None]
    if j.ndim != 3 or j.shape[-1] != 3:
        raise InputError("joints", "an array of shape (T, 14, 3)", f"shape {np.shape(joints)}")
    if not np.all(np.isfinite(j)):
        raise InputError("joints", "finite joint positions", "NaN or inf values")
    g = {n: j[:, i] for n, i in _J.items()}
    root = 0.5 * (g["l_hip"] + g["r_hip"])
    lat = _unit(g["r_hip"] - g["l_hip"])
    roll = np.arcsin(np.clip(-lat[:, 2], -1, 1))
    yaw = np.arctan2(lat[:, 1], lat[:, 0])
    zero = np.zeros(len(j))
    Rp = rot_z(yaw) @ rot_y(roll)
    u = np.einsum("tji,tj->ti", Rp, _unit(g["neck"] - root))
    lean = np.arctan2(u[:, 1], u[:, 2])
    Rl = Rp @ rot_x(-lean)
    d = np.einsum("tji,tj->ti", Rl, g["r_shoulder"] - g["l_shoulder"])
    twist = np.arctan2(d[:, 1], d[:, 0])
    Rt = Rl @ rot_z(twist)
    h = np.einsum("tji,tj->ti", Rt, _unit(g["head"] - g["neck"]))
    head_roll = np.arcsin(np.clip(h[:, 0], -1, 1))
    head_pitch = np.arctan2(h[:, 1], h[:, 2])
    shoulder = np.zeros((len(j), 2, 3))
    hip = np.zeros((len(j), 2, 3))
    elbow = np.zeros((len(j), 2))
    knee = np.zeros((len(j), 2))
    for side, pre in ((LEFT, "l_"), (RIGHT, "r_")):
        shoulder[:, side], elbow[:, side] = _limb_angles(Rt, g[pre + "shoulder"], g[pre + "elbow"],
                                                         g[pre + "wrist"], side, +1.0)
        hip[:, side], knee[:, side] = _limb_angles(Rp, g[pre + "hip"], g[pre + "knee"],
                                                   g[pre + "ankle"], side, -1.0)
    return Pose14(root=root, yaw=yaw, pitch=zero, roll=roll, lean=lean, twist=twist,
                  head_pitch=head_pitch, head_roll=head_roll, shoulder=shoulder, elbow=elbow,
                  hip=hip, knee=knee)


# -------------------------------------------------------------- bone lengths
def bone_lengths14(proportions: BodyProportions) -> np.ndarray:
    """Bone lengths of the 14-joint skeleton for ``proportions``.

    Returns
    -------
    ndarray of shape (13,)
        Metres, in the order of ``SKELETON_14.bones``.
    """
    p = proportions
    by_child = {
        "head": p.neck_to_head,
        "l_shoulder": np.hypot(p.shoulder_half_width, p.shoulder_drop),
        "l_elbow": p.upper_arm, "l_wrist": p.forearm,
        "l_hip": np.hypot(p.hip_half_width, p.torso),
        "l_knee": p.thigh, "l_ankle": p.shank,
    }
    out = []
    for _, c in SKELETON_14.bones:
        name = SKELETON_14.joint_names[c]
        out.append(by_child[name.replace("r_", "l_")])
    return np.array(out)


def sequence_bone_lengths(joints: np.ndarray) -> np.ndarray:
    """Per-frame bone lengths of a joint sequence.

    Parameters
    ----------
    joints : ndarray of shape (T, 14, 3) or (14, 3)

    Returns
    -------
    ndarray of shape (T, 13) or (13,)
        Metres, in the order of ``SKELETON_14.bones``; NaN where a joint is missing.
    """
    return SKELETON_14.bone_lengths(joints)


def set_bone_lengths(joints: np.ndarray, lengths: np.ndarray) -> np.ndarray:
    """Keep every bone's direction and give it a new length (forward kinematics from the neck).

    Parameters
    ----------
    joints : ndarray of shape (T, 14, 3) or (14, 3)
        Metres.
    lengths : ndarray of shape (13,)
        Metres, in the order of ``SKELETON_14.bones``.

    Returns
    -------
    ndarray of the shape of ``joints``
        The neck stays where it was; each other joint is its parent plus the
        bone length times the original bone's unit direction.
    """
    j = SKELETON_14.check_joints(joints)
    L = np.asarray(lengths, float)
    if L.shape != (len(SKELETON_14.bones),) or not np.all(np.isfinite(L)) or np.any(L <= 0):
        raise InputError("lengths", f"{len(SKELETON_14.bones)} positive bone lengths",
                         f"shape {L.shape}" if L.shape != (len(SKELETON_14.bones),) else repr(L))
    out = np.empty_like(j)
    root = SKELETON_14.index("neck")
    out[..., root, :] = j[..., root, :]
    bone_of = {c: b for b, (_, c) in enumerate(SKELETON_14.bones)}
    todo = [root]
    while todo:
        p = todo.pop()
        for c in SKELETON_14.children(p):
            d = j[..., c, :] - j[..., p, :]
            n = np.linalg.norm(d, axis=-1, keepdims=True)
            out[..., c, :] = out[..., p, :] + L[bone_of[c]] * d / np.maximum(n, 1e-12)
            todo.append(c)
    return out


def leg_reach(proportions: BodyProportions, min_knee_flexion=KNEE_MIN_FLEXION):
    """Largest hip-to-ankle distance (m) with the knee flexed at least ``min_knee_flexion`` rad.

    ``min_knee_flexion`` may be an array; the result then has its shape.
    """
    a, b = proportions.thigh, proportions.shank
    r = np.sqrt(a * a + b * b + 2 * a * b * np.cos(min_knee_flexion))
    return float(r) if np.ndim(r) == 0 else r


# ------------------------------------------------------------------------ IK
def two_bone_ik(base: np.ndarray, target: np.ndarray, l1: float, l2: float, pole: np.ndarray,
                max_reach: float | None = None):
    """Place the middle joint of a two-segment chain so that its end reaches ``target``.

    Parameters
    ----------
    base : ndarray of shape (T, 3)
        Proximal joint (hip, shoulder), metres.
    target : ndarray of shape (T, 3)
        Wanted end position (ankle, wrist), metres.
    l1, l2 : float
        Segment lengths, metres.
    pole : ndarray of shape (T, 3) or (3,)
        Direction the middle joint bends toward (e.g. forward for the knee).
    max_reach : float or ndarray of shape (T,), optional
        Longest allowed base-to-end distance (default ``l1 + l2``); targets
        farther away are pulled toward the base along the same ray.

    Returns
    -------
    mid : ndarray of shape (T, 3)
    end : ndarray of shape (T, 3)
        ``end == target`` where the target is reachable.
    reached : ndarray of shape (T,), bool
    """
    base = np.asarray(base, float)
    target = np.asarray(target, float)
    pole = np.broadcast_to(np.asarray(pole, float), base.shape)
    d_max = l1 + l2 if max_reach is None else np.minimum(np.asarray(max_reach, float), l1 + l2)
    d_min = abs(l1 - l2) + 1e-6
    v = target - base
    d = np.linalg.norm(v, axis=-1)
    u = v / np.maximum(d, 1e-12)[:, None]
    reached = (d <= d_max + 1e-12) & (d >= d_min)
    dc = np.clip(d, d_min, d_max)
    cos_a = np.clip((l1 * l1 + dc * dc - l2 * l2) / (2 * l1 * dc), -1.0, 1.0)
    w = pole - np.sum(pole * u, -1, keepdims=True) * u
    wn = np.linalg.norm(w, axis=-1)
    # a pole parallel to the chain: bend toward any perpendicular direction
    fallback = np.cross(u, np.where(np.abs(u[:, 2:3]) < 0.9, [[0.0, 0.0, 1.0]], [[1.0, 0.0, 0.0]]))
    w = np.where(wn[:, None] > 1e-9, w, fallback)
    w = _unit(w)
    mid = base + l1 * (cos_a[:, None] * u + np.sqrt(1 - cos_a ** 2)[:, None] * w)
    end = base + dc[:, None] * u
    return mid, end, reached


# -------------------------------------------------------------------- ground
def align_to_ground(joints: np.ndarray, ankle_height: float, mode: str = "sequence",
                    percentile: float = 5.0) -> np.ndarray:
    """Shift a joint sequence vertically so that the feet stand on the ground z = 0.

    Parameters
    ----------
    joints : ndarray of shape (T, 14, 3)
        Metres, z up.
    ankle_height : float
        Height of the ankle joint above the floor when standing, metres.
    mode : {"sequence", "frame"}
        ``"sequence"``: one shift for the whole sequence that puts the
        ``percentile``-th percentile of the per-frame lowest ankle (an actual
        frame, numpy's ``method="lower"``) at ``ankle_height`` (jumps keep
        their flight), then every frame whose lowest ankle would still be
        below ``ankle_height`` is lifted to it.
        ``"frame"``: every frame is shifted so its lowest ankle is exactly at
        ``ankle_height`` (for motions that always keep a foot down).
    percentile : float
        Percentile used by ``"sequence"``.

    Returns
    -------
    ndarray of shape (T, 14, 3)
        The shifted copy; no ankle is below ``ankle_height``.
    """
    j = SKELETON_14.check_joints(joints).copy()
    if j.ndim != 3 or j.shape[-1] != 3:
        raise InputError("joints", "an array of shape (T, 14, 3)", f"shape {j.shape}")
    if not np.isfinite(ankle_height) or ankle_height < 0:
        raise InputError("ankle_height", "a non-negative height in metres", repr(ankle_height))
    low = np.nanmin(j[:, [_J["l_ankle"], _J["r_ankle"]], 2], axis=1)
    if mode == "frame":
        shift = np.where(np.isfinite(low), ankle_height - low, 0.0)
    elif mode == "sequence":
        base = ankle_height - np.nanpercentile(low, percentile, method="lower")
        shift = np.where(np.isfinite(low), np.maximum(base, ankle_height - low), base)
    else:
        raise InputError("mode", "'sequence' or 'frame'", repr(mode))
    j[..., 2] += shift[:, None]
    return j


# ------------------------------------------------------------------ timing
def resample(joints: np.ndarray, src_fps: float, dst_fps: float) -> np.ndarray:
    """Resample a joint sequence to another frame rate by linear interpolation in time.

    Frame ``k`` of the output is at time ``k / dst_fps``; the output covers
    the input's duration ``(T - 1) / src_fps``.  A joint missing (NaN) in either
    neighbouring input frame is missing in the output frame.

    Parameters
    ----------
    joints : ndarray of shape (T, J, D)
    src_fps, dst_fps : float
        Frames per second, > 0.

    Returns
    -------
    ndarray of shape (T', J, D)
        ``T' = floor((T - 1) * dst_fps / src_fps) + 1``.
    """
    j = np.asarray(joints, float)
    if j.ndim != 3 or j.shape[0] < 1:
        raise InputError("joints", "an array of shape (T, J, D) with T >= 1", f"shape {j.shape}")
    for name, v in (("src_fps", src_fps), ("dst_fps", dst_fps)):
        if not (np.isfinite(v) and v > 0):
            raise InputError(name, "a positive frame rate", repr(v))
    n_out = int(np.floor((j.shape[0] - 1) * dst_fps / src_fps + 1e-9)) + 1
    x = np.arange(n_out) * (src_fps / dst_fps)
    i0 = np.clip(np.floor(x).astype(int), 0, j.shape[0] - 1)
    i1 = np.minimum(i0 + 1, j.shape[0] - 1)
    w = (x - i0)[:, None, None]
    return np.where(w > 0, (1 - w) * j[i0] + w * j[i1], j[i0])
