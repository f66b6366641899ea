"""Planning machinery of the procedural motions (:mod:`toolkit.motion.library`).

A motion is a :class:`_Plan` (pelvis path, trunk, head and arm angles, ankle
targets, which feet are planted) drawn by a builder from a :class:`_Ctx`
(proportions, frames, the random generator and the parameters drawn), then
turned into joints by :func:`_finish`: pelvis lowered wherever a planted foot
would be out of reach, two-bone inverse kinematics for the legs, forward
kinematics.  The builders live in :mod:`toolkit.motion.gait` (walk, run) and
:mod:`toolkit.motion.actions` (in-place motions).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.interpolate import PchipInterpolator

from toolkit.anthropometry.proportions import BodyProportions
from toolkit.motion.kinematics import (
    KNEE_MIN_FLEXION,
    LEFT,
    RIGHT,
    Pose14,
    _limb_angles,
    forward_kinematics,
    leg_reach,
    rot_x,
    rot_y,
    rot_z,
    two_bone_ik,
)

#: In-place motions start within this distance of the origin, metres.
PLACEMENT_RADIUS_M = 1.0
#: Toe lever: horizontal ankle-to-metatarsal-head distance as a fraction of
#: stature (foot length is about 0.15 of stature, the ankle sits over its
#: rear quarter).
TOE_LEVER_RATIO = 0.08
#: Temperature of the soft minimum that lowers the pelvis to keep planted
#: feet in reach, metres (the pelvis is never above the hard limit).
REACH_SOFTNESS_M = 0.003


@dataclass(frozen=True)
class Motion:
    """A generated motion with its ground truth.

    Attributes
    ----------
    name : str
    fps : float
    joints : ndarray of shape (T, 14, 3)
        World, metres, z up, order of ``SKELETON_14.joint_names``.
    pose : Pose14
        The joint angles that produce ``joints``.
    contacts : ndarray of shape (T, 2), bool
        Left and right foot flat on the ground (ankle planted, not moving).
    params : dict
        The parameters drawn from ``rng`` (name -> float, int or str).
    ankle : ndarray of shape (T, 2) or None
        Foot rotation about the ankle relative to the shank, radians (left,
        right; > 0 lifts the toes), for motions that move the ankle (``rom``);
        not part of the 14-joint skeleton.  None: the foot is rigid with the shank.
    """

    name: str
    fps: float
    joints: np.ndarray
    pose: Pose14
    contacts: np.ndarray
    params: dict = field(default_factory=dict)
    ankle: np.ndarray | None = None

    @property
    def n_frames(self) -> int:
        return self.joints.shape[0]


# ------------------------------------------------------------------ helpers
def _smooth(x):
    """Minimum-jerk step 0 -> 1 on [0, 1] (zero velocity and acceleration at both ends)."""
    x = np.clip(x, 0.0, 1.0)
    return x * x * x * (10 - 15 * x + 6 * x * x)


def _ramp(t, t0, t1):
    return _smooth((t - t0) / max(t1 - t0, 1e-9))


def _bump(x):
    """0 -> 1 -> 0 on [0, 1], peak at 1/3, zero velocity at the end."""
    x = np.clip(x, 0.0, 1.0)
    return 6.75 * x * (1 - x) ** 2


def _keys(t, times, values):
    """Shape-preserving (PCHIP) interpolation of key values, held constant outside the keys.

    ``values`` may be (K,) or (K, D); no overshoot beyond neighbouring keys.
    """
    times = np.asarray(times, float)
    values = np.asarray(values, float)
    tc = np.clip(t, times[0], times[-1])
    return PchipInterpolator(times, values, axis=0)(tc)


def _softmin(stack, tau):
    """Soft minimum along axis 0, never above the hard minimum."""
    m = np.min(stack, axis=0)
    return m - tau * np.log(np.sum(np.exp(-(stack - m) / tau), axis=0))


def _heading_vectors(yaw):
    """Forward and right unit vectors (T, 3) of a body with heading ``yaw``."""
    c, s = np.cos(yaw), np.sin(yaw)
    z = np.zeros_like(yaw)
    return np.stack([-s, c, z], -1), np.stack([c, s, z], -1)


class _Ctx:
    """Inputs of one motion plan; draws and records parameters."""

    def __init__(self, proportions: BodyProportions, n_frames: int, fps: float, rng, area_m: float | None = None):
        self.p = proportions
        self.area_m = area_m      # walks and runs keep the pelvis within this of their centre (None: no bound)
        self.fps = float(fps)
        self.t = np.arange(n_frames) / self.fps
        self.T = n_frames
        self.rng = rng
        self.params: dict = {}
        self.leg = proportions.thigh + proportions.shank
        self.reach = leg_reach(proportions)

    @property
    def duration(self) -> float:
        return self.t[-1] if self.T > 1 else 0.0

    def uniform(self, name, lo, hi):
        v = float(self.rng.uniform(lo, hi))
        self.params[name] = v
        return v

    def deg(self, name, lo, hi):
        """A uniform angle drawn in degrees, recorded in degrees, returned in radians."""
        return np.deg2rad(self.uniform(name, lo, hi))

    def choice(self, name, options):
        v = options[int(self.rng.integers(len(options)))]
        self.params[name] = v
        return v

    def standing_height(self, lateral_offset):
        """Pelvis-centre height of a person standing with knees at the minimum flexion."""
        return self.p.ankle_height + np.sqrt(self.reach ** 2 - lateral_offset ** 2)

    def placement(self):
        """Random centre (within PLACEMENT_RADIUS_M) and heading."""
        r = PLACEMENT_RADIUS_M * np.sqrt(self.uniform("place_radius_frac", 0.0, 1.0))
        a = self.uniform("place_angle", 0.0, 2 * np.pi)
        heading = self.uniform("heading", 0.0, 2 * np.pi)
        return np.array([r * np.cos(a), r * np.sin(a)]), heading


class _Plan:
    """Everything a motion specifies before inverse kinematics (arrays over T frames)."""

    def __init__(self, T):
        z = np.zeros(T)
        self.pelvis_xy = np.zeros((T, 2))
        self.pelvis_z = z.copy()          # nominal height; lowered where feet are out of reach
        self.yaw, self.pitch, self.roll = z.copy(), z.copy(), z.copy()
        self.lean, self.twist = z.copy(), z.copy()
        self.head_pitch, self.head_roll = z.copy(), z.copy()
        self.shoulder = np.zeros((T, 2, 3))
        self.elbow = np.zeros((T, 2))
        self.ankle = np.zeros((T, 2, 3))   # ankle targets, world
        self.planted = np.zeros((T, 2), bool)   # ankle static on the ground
        self.in_reach = np.ones((T, 2), bool)   # targets the pelvis height must respect
        self.knee_out = np.full(T, 0.1)         # outward component of the knee pole
        self.min_knee = np.full((T, 2), KNEE_MIN_FLEXION)  # knee flexion never below this

    def relaxed_arms(self, ctx, prefix="arm"):
        abd = ctx.deg(f"{prefix}_abduction_deg", 5.0, 12.0)
        el = ctx.deg(f"{prefix}_elbow_deg", 8.0, 20.0)
        self.shoulder[:, :, 1] = abd
        self.elbow[:, :] = el


def _finish(ctx: _Ctx, plan: _Plan, name: str) -> Motion:
    """Pelvis height from reach, leg IK, angles, forward kinematics."""
    p = ctx.p
    T = ctx.T
    Rp = rot_z(plan.yaw) @ rot_x(-plan.pitch) @ rot_y(plan.roll)
    hip_off = np.stack([Rp @ np.array([-p.hip_half_width, 0, 0]),
                        Rp @ np.array([p.hip_half_width, 0, 0])], 1)  # (T, 2, 3)
    limits = [plan.pelvis_z]
    reach = leg_reach(p, np.maximum(plan.min_knee, KNEE_MIN_FLEXION))  # (T, 2)
    for side in (LEFT, RIGHT):
        a = plan.ankle[:, side]
        dxy = np.linalg.norm(plan.pelvis_xy + hip_off[:, side, :2] - a[:, :2], axis=-1)
        zmax = a[:, 2] + np.sqrt(np.maximum(reach[:, side] ** 2 - dxy ** 2, 0.0)) - hip_off[:, side, 2]
        limits.append(np.where(plan.in_reach[:, side], zmax, np.inf))
    z = _softmin(np.stack(limits), REACH_SOFTNESS_M)
    root = np.column_stack([plan.pelvis_xy, z])
    hip = np.zeros((T, 2, 3))
    knee = np.zeros((T, 2))
    fwd = Rp[:, :, 1]
    right = Rp[:, :, 0]
    for side, lat in ((LEFT, -1.0), (RIGHT, 1.0)):
        hp = root + hip_off[:, side]
        pole = fwd + (lat * plan.knee_out)[:, None] * right
        kn, an, _ = two_bone_ik(hp, plan.ankle[:, side], p.thigh, p.shank, pole,
                                max_reach=reach[:, side])
        hip[:, side], knee[:, side] = _limb_angles(Rp, hp, kn, an, side, -1.0)
    pose = Pose14(root=root, yaw=plan.yaw, pitch=plan.pitch, roll=plan.roll, lean=plan.lean,
                  twist=plan.twist, head_pitch=plan.head_pitch, head_roll=plan.head_roll,
                  shoulder=plan.shoulder, elbow=np.maximum(plan.elbow, 0.0), hip=hip, knee=knee)
    joints = forward_kinematics(p, pose)
    return Motion(name=name, fps=ctx.fps, joints=joints, pose=pose, contacts=plan.planted.copy(),
                  params=dict(ctx.params))


def _heel_off(ctx, alpha):
    """Forward and upward ankle displacement when the heel rises by ``alpha`` rad about the toes."""
    a = TOE_LEVER_RATIO * ctx.p.height
    h = ctx.p.ankle_height
    dx = a * (1 - np.cos(alpha)) + h * np.sin(alpha)
    dz = a * np.sin(alpha) - h * (1 - np.cos(alpha))
    return dx, dz

