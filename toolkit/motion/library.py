"""Procedural motion library for the 14-joint skeleton.

Every motion is built the same way: a plan of the pelvis path, trunk, head
and arm angles, and ankle targets (planted feet stay exactly where they were
put), then two-bone inverse kinematics for the legs with the pelvis lowered
wherever a planted foot would otherwise be out of reach, then
:func:`~toolkit.motion.kinematics.forward_kinematics`.  So bone lengths are
those of the :class:`BodyProportions` in every frame, a planted ankle is at
``ankle_height`` above the ground and does not move, no ankle goes below
``ankle_height``, and knees never hyper-extend.

Each motion's parameters are drawn from ``rng`` (same seed, same motion) and
recorded in :attr:`Motion.params`; ``docs/motion.md`` lists them and their
ranges.  The subject stays near the origin: in-place motions start within
:data:`PLACEMENT_RADIUS_M` of it, walks and runs follow a line through the
origin when it fits within :data:`LINE_HALF_LENGTH_M` and otherwise a circle
around it, so that ``|x|, |y| < 4 m``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.interpolate import CubicHermiteSpline, PchipInterpolator

from toolkit.anthropometry.proportions import BodyProportions
from toolkit.errors import InputError
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
from toolkit.observe import as_observer
from toolkit.skeleton import SKELETON_14

__all__ = ["MOTIONS", "Motion", "synthesize_motion", "generate_motion", "GRAVITY_M_S2",
           "WALK_CADENCE_HZ", "RUN_CADENCE_HZ", "PLACEMENT_RADIUS_M", "LINE_HALF_LENGTH_M"]

#: Motion names understood by :func:`generate_motion`.
MOTIONS = ("walk", "run", "jump", "kick", "turn", "wave", "crouch", "idle")

#: Standard gravity, m/s^2 (ballistic flight of jumps).
GRAVITY_M_S2 = 9.81
#: Step frequency (steps per second) range of walking; mean about 1.8 Hz
#: (typical adult cadence 100-115 steps/min).
WALK_CADENCE_HZ = (1.65, 1.95)
#: Step frequency range of running; mean about 2.8 Hz (160-180 steps/min).
RUN_CADENCE_HZ = (2.6, 3.0)
#: In-place motions start within this distance of the origin, metres.
PLACEMENT_RADIUS_M = 1.0
#: A walk or run goes along a straight line only if it stays within this
#: distance of the origin; otherwise it follows a circle, metres.
LINE_HALF_LENGTH_M = 3.0
#: Toe lever: horizontal ankle-to-metatarsal-head distance as a fraction of
#: stature (foot length is about 0.15 of stature, the ankle sits over its
#: rear quarter).
TOE_LEVER_RATIO = 0.08
#: Temperature of the soft minimum that lowers the pelvis to keep planted
#: feet in reach, metres (the pelvis is never above the hard limit).
REACH_SOFTNESS_M = 0.003
#: Normalised horizontal speed of the ankle at the start of swing (Hermite
#: slope; 0 = starts at rest, 1 = starts at the mean swing speed).
SWING_START_SLOPE = 0.8
#: Safety margin below the reach limit used for the planned heights of
#: jumps (takeoff), metres.
TAKEOFF_MARGIN_M = 0.02


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
    """

    name: str
    fps: float
    joints: np.ndarray
    pose: Pose14
    contacts: np.ndarray
    params: dict = field(default_factory=dict)

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

    def __init__(self, proportions: BodyProportions, n_frames: int, fps: float, rng):
        self.p = proportions
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


# --------------------------------------------------------------------- gait
def _gait(ctx: _Ctx, running: bool) -> _Plan:
    p, t, T = ctx.p, ctx.t, ctx.T
    H = p.height
    if running:
        cadence = ctx.uniform("cadence_hz", *RUN_CADENCE_HZ)
        step = H * ctx.uniform("step_length_ratio", 0.50, 0.62)
        duty = ctx.uniform("duty_factor", 0.33, 0.38)
        heel_off_at = duty * ctx.uniform("heel_off_fraction", 0.45, 0.6)
        ahead = ctx.uniform("contact_ahead_ratio", 0.25, 0.32)
        knee_stance = ctx.deg("stance_knee_deg", 30.0, 45.0)
        knee_swing = ctx.deg("swing_knee_deg", 95.0, 120.0)
        alpha_max = ctx.deg("toe_off_angle_deg", 30.0, 40.0)
        lift = ctx.uniform("swing_lift_m", 0.25, 0.38) * H / 1.75
        drop = ctx.uniform("pelvis_drop_m", 0.03, 0.06)
        bob = -ctx.uniform("pelvis_bob_m", 0.02, 0.035)
        sway = ctx.uniform("pelvis_sway_m", 0.005, 0.015)
        lean0 = ctx.deg("lean_deg", 6.0, 12.0)
        arm_swing = ctx.deg("arm_swing_deg", 25.0, 40.0)
        elbow0 = ctx.deg("elbow_deg", 75.0, 100.0)
        arm_rot = ctx.deg("arm_internal_rotation_deg", 10.0, 30.0)
    else:
        cadence = ctx.uniform("cadence_hz", *WALK_CADENCE_HZ)
        step = H * ctx.uniform("step_length_ratio", 0.37, 0.45)
        duty = ctx.uniform("duty_factor", 0.58, 0.62)
        heel_off_at = ctx.uniform("heel_off_phase", 0.30, 0.36)
        ahead = ctx.uniform("contact_ahead_ratio", 0.35, 0.42)
        knee_stance = ctx.deg("stance_knee_deg", 10.0, 18.0)
        knee_swing = ctx.deg("swing_knee_deg", 55.0, 68.0)
        alpha_max = ctx.deg("toe_off_angle_deg", 30.0, 40.0)
        lift = ctx.uniform("swing_lift_m", 0.10, 0.16) * H / 1.75
        drop = ctx.uniform("pelvis_drop_m", 0.01, 0.03)
        bob = ctx.uniform("pelvis_bob_m", 0.012, 0.022)
        sway = ctx.uniform("pelvis_sway_m", 0.015, 0.03)
        lean0 = ctx.deg("lean_deg", 1.0, 5.0)
        arm_swing = ctx.deg("arm_swing_deg", 12.0, 25.0)
        elbow0 = ctx.deg("elbow_deg", 10.0, 25.0)
        arm_rot = ctx.deg("arm_internal_rotation_deg", 0.0, 10.0)
    pelvis_rot = ctx.deg("pelvis_rotation_deg", 3.0, 6.0)
    thorax_rot = ctx.deg("thorax_rotation_deg", 2.0, 5.0)
    pelvis_roll = ctx.deg("pelvis_roll_deg", 2.0, 5.0)
    half_width = p.hip_half_width * ctx.uniform("step_width_ratio", 0.8, 1.2)
    phase0 = ctx.uniform("phase", 0.0, 1.0)
    f = cadence / 2.0                      # strides per second
    speed = step * cadence
    # the ankle lands ``ahead * step`` in front of the pelvis; the pelvis passes
    # over it ``mid`` of a stride after contact
    mid = ahead * step / (2 * step)
    ctx.params["speed_m_s"] = speed

    # path: a line through the origin when it fits, else a circle around it
    travel = speed * max(ctx.duration, 1e-9)
    offset = ctx.uniform("path_offset_m", -0.3, 0.3)
    heading0 = ctx.uniform("heading", 0.0, 2 * np.pi)
    line = travel / 2 + abs(offset) + 0.2 <= LINE_HALF_LENGTH_M and ctx.uniform("line_or_circle", 0, 1) < 0.6
    if line:
        ctx.params["path"] = "line"
        line_dir = np.array([-np.sin(heading0), np.cos(heading0)])
        line_left = np.array([-line_dir[1], line_dir[0]])   # left of the direction of travel
        line_start = -line_dir * travel / 2 + line_left * offset

        def path(s):
            pos = line_start[None] + s[:, None] * line_dir[None]
            return pos, np.full(len(s), heading0)
    else:
        ctx.params["path"] = "circle"
        radius = ctx.uniform("circle_radius_m", 2.0, 2.8 if not running else 3.2)
        ccw = ctx.choice("circle_direction", ("ccw", "cw")) == "ccw"
        sign = 1.0 if ccw else -1.0
        centre = np.array([offset, 0.0])
        theta0 = heading0

        def path(s):
            th = theta0 + sign * s / radius
            pos = centre[None] + radius * np.column_stack([np.cos(th), np.sin(th)])
            # tangent direction (-sin, cos) * sign -> heading angle
            head = th + (0.0 if ccw else np.pi)
            return pos, head

    s_t = speed * t
    P, psi = path(s_t)
    fwd, right = _heading_vectors(psi)
    phase = f * t + phase0

    plan = _Plan(T)
    ah = p.ankle_height
    dx_max, dz_max = _heel_off(ctx, alpha_max)
    for side, off, lat in ((LEFT, 0.0, -1.0), (RIGHT, 0.5, 1.0)):
        u = phase - off
        k = np.floor(u).astype(int)
        local = u - k
        ks = np.arange(k.min() - 1, k.max() + 3)
        t_fp = (ks + mid + off - phase0) / f
        Pf, psif = path(speed * t_fp)
        fwd_f, right_f = _heading_vectors(psif)
        jitter = np.clip(ctx.rng.normal(0.0, 0.008, (len(ks), 2)), -0.02, 0.02)
        fp = Pf + lat * half_width * right_f[:, :2] + jitter
        i = k - ks[0]
        here, nxt = fp[i], fp[i + 1]
        fdir = fwd_f[i, :2]
        target = np.zeros((T, 3))
        flat = local < heel_off_at
        heel = (local >= heel_off_at) & (local < duty)
        swing = local >= duty
        target[:, :2] = here
        target[:, 2] = ah
        al = alpha_max * _smooth((local - heel_off_at) / (duty - heel_off_at))
        dx, dz = _heel_off(ctx, al)
        target[heel, :2] = here[heel] + dx[heel, None] * fdir[heel]
        target[heel, 2] = ah + dz[heel]
        tau = (local - duty) / (1 - duty)
        lift_off = here + dx_max * fdir
        # horizontal swing: leaves with some speed, lands with none
        tc = np.clip(tau, 0, 1)
        prog = 3 * tc ** 2 - 2 * tc ** 3 + SWING_START_SLOPE * (tc ** 3 - 2 * tc ** 2 + tc)
        sw_xy = lift_off + (nxt - lift_off) * prog[:, None]
        sw_z = ah + dz_max * (1 - _smooth(2 * tau)) + lift * _bump(tau)
        target[swing, :2] = sw_xy[swing]
        target[swing, 2] = sw_z[swing]
        plan.ankle[:, side] = target
        plan.planted[:, side] = flat
        # the pelvis height respects flat feet and the landing half of swing;
        # push-off and early swing are pulled toward the hip instead (the heel
        # then rises further, as in a real push-off)
        plan.in_reach[:, side] = flat | (swing & (tau > 0.5))
        # knee flexion schedule over the cycle (loading, push-off, swing peak, landing)
        if running:
            keys_u = [0.0, 0.5 * duty, duty, duty + 0.35 * (1 - duty), duty + 0.85 * (1 - duty), 1.0]
            keys_k = [np.deg2rad(15), knee_stance, np.deg2rad(25), knee_swing, np.deg2rad(20),
                      np.deg2rad(15)]
        else:
            keys_u = [0.0, 0.12, heel_off_at, duty, duty + 0.3 * (1 - duty),
                      duty + 0.85 * (1 - duty), 1.0]
            keys_k = [np.deg2rad(5), knee_stance, np.deg2rad(5), np.deg2rad(35), knee_swing,
                      np.deg2rad(5), np.deg2rad(5)]
        plan.min_knee[:, side] = PchipInterpolator(keys_u, keys_k)(local)
    # pelvis and trunk
    w = 2 * np.pi
    left_dir = -right[:, :2]
    plan.pelvis_xy = P + (sway * np.cos(w * (phase - mid)))[:, None] * left_dir
    plan.pelvis_z = ctx.standing_height(0.0) - drop + bob * np.cos(2 * w * (phase - mid))
    plan.yaw = psi - pelvis_rot * np.cos(w * phase)
    plan.roll = pelvis_roll * np.cos(w * (phase - mid))
    plan.pitch[:] = np.deg2rad(3.0)
    plan.lean = lean0 + 0.25 * lean0 * np.cos(2 * w * (phase - mid))
    plan.twist = (pelvis_rot + thorax_rot) * np.cos(w * phase)
    plan.head_pitch = -0.6 * plan.lean
    swing_arm = arm_swing * np.cos(w * (phase - 0.05))
    plan.shoulder[:, LEFT, 0] = -swing_arm + (np.deg2rad(5.0) if running else 0.0)
    plan.shoulder[:, RIGHT, 0] = swing_arm + (np.deg2rad(5.0) if running else 0.0)
    plan.shoulder[:, :, 1] = np.deg2rad(8.0)
    plan.shoulder[:, :, 2] = arm_rot
    plan.elbow[:, LEFT] = elbow0 + 0.4 * np.maximum(-swing_arm, 0)
    plan.elbow[:, RIGHT] = elbow0 + 0.4 * np.maximum(swing_arm, 0)
    return plan


def _walk(ctx):
    return _gait(ctx, running=False)


def _run(ctx):
    return _gait(ctx, running=True)


# ------------------------------------------------------------ in-place base
def _stand(ctx: _Ctx, plan: _Plan, centre, heading, half_width):
    """Feet planted beside ``centre`` facing ``heading``; pelvis over them, standing."""
    fwd, right = _heading_vectors(np.full(ctx.T, heading))
    for side, lat in ((LEFT, -1.0), (RIGHT, 1.0)):
        plan.ankle[:, side, :2] = centre + lat * half_width * right[:, :2]
        plan.ankle[:, side, 2] = ctx.p.ankle_height
        plan.planted[:, side] = True
    plan.pelvis_xy[:] = centre
    plan.yaw[:] = heading
    plan.pelvis_z[:] = ctx.standing_height(max(half_width - ctx.p.hip_half_width, 0.0))
    return fwd, right


def _breathing(ctx, plan, fwd, right, scale=1.0):
    """Small postural sway and head motion of quiet standing."""
    t = ctx.t
    f1 = ctx.uniform("sway_hz", 0.15, 0.35)
    a1 = scale * ctx.uniform("sway_m", 0.005, 0.015)
    ph = ctx.uniform("sway_phase", 0, 2 * np.pi)
    plan.pelvis_xy += (a1 * np.sin(2 * np.pi * f1 * t + ph))[:, None] * right[:, :2]
    plan.pelvis_xy += (0.5 * a1 * np.sin(2 * np.pi * 0.7 * f1 * t + 2 * ph))[:, None] * fwd[:, :2]
    plan.lean += np.deg2rad(2.0) + np.deg2rad(1.0) * np.sin(2 * np.pi * 0.5 * f1 * t + ph)
    plan.head_pitch += np.deg2rad(3.0) * np.sin(2 * np.pi * 0.3 * t + 3 * ph)
    plan.head_roll += np.deg2rad(2.0) * np.sin(2 * np.pi * 0.23 * t + ph)


def _repeat_times(ctx, first, make_event):
    """Start times of events: ``make_event(i) -> (duration, pause)`` until the clip ends."""
    starts, t0, i = [], first, 0
    while True:
        starts.append(t0)
        dur, pause = make_event(i)
        t0 += dur + pause
        i += 1
        if t0 > ctx.duration or i > 100:
            break
    return starts


# --------------------------------------------------------------------- jump
def _jump(ctx: _Ctx) -> _Plan:
    p, t, T = ctx.p, ctx.t, ctx.T
    plan = _Plan(T)
    centre, heading = ctx.placement()
    half_width = p.hip_half_width + ctx.uniform("stance_extra_m", 0.0, 0.05)
    fwd, right = _stand(ctx, plan, centre, heading, half_width)
    f2, r2 = fwd[0, :2], right[0, :2]
    plan.relaxed_arms(ctx)
    z_stand = ctx.standing_height(half_width - p.hip_half_width) - 0.005
    depth = ctx.leg * ctx.uniform("crouch_depth_ratio", 0.18, 0.30)
    apex = ctx.uniform("apex_height_m", 0.12, 0.35)
    distance = ctx.uniform("jump_distance_m", 0.0, 0.45)
    v0 = np.sqrt(2 * GRAVITY_M_S2 * apex)
    t_flight = 2 * v0 / GRAVITY_M_S2
    land_depth = ctx.leg * ctx.uniform("landing_depth_ratio", 0.10, 0.20)
    lead = ctx.uniform("lead_in_s", 0.2, 0.6)
    t_down = ctx.uniform("crouch_s", 0.45, 0.7)
    arm_back = ctx.deg("arm_back_deg", 30.0, 60.0)
    arm_up = ctx.deg("arm_up_deg", 110.0, 160.0)
    lean_crouch = ctx.deg("crouch_lean_deg", 25.0, 40.0)
    tuck = ctx.uniform("tuck_m", 0.03, 0.15)
    lat_off = half_width - p.hip_half_width
    z_to = p.ankle_height + np.sqrt(ctx.reach ** 2 - (0.15 * distance) ** 2 - lat_off ** 2) - TAKEOFF_MARGIN_M
    z_to = max(z_to, z_stand)
    t_push = min(ctx.uniform("push_s", 0.25, 0.32), 0.95 * 3 * (z_to - (z_stand - depth)) / v0)
    t_land = min(ctx.uniform("landing_s", 0.25, 0.4), 0.95 * 3 * land_depth / v0)
    t_rec = ctx.uniform("recover_s", 0.5, 0.8)
    rest = ctx.uniform("rest_s", 0.4, 1.2)
    one = t_down + t_push + t_flight + t_land + t_rec
    starts = _repeat_times(ctx, lead, lambda i: (one, rest))
    ctx.params["n_jumps"] = len(starts)
    # keep the sequence of jumps centred on the placement
    x0 = -0.5 * distance * len(starts)
    zk, xk, tk = [(z_stand, 0.0)], [(x0, 0.0)], [0.0]
    lean_k, arm_k, el_k, kt = [np.deg2rad(2)], [0.0], [0.25], [0.0]
    flights = []
    X = x0
    for s in starts:
        t1, t2 = s + t_down, s + t_down + t_push
        t3 = t2 + t_flight
        t4, t5 = t3 + t_land, t3 + t_land + t_rec
        vh = 0.7 * distance / t_flight
        tk += [s, t1, t2, t3, t4, t5]
        zk += [(z_stand, 0), (z_stand - depth, 0), (z_to, v0), (z_to, -v0), (z_to - land_depth, 0),
               (z_stand, 0)]
        xk += [(X, 0), (X - 0.04 * depth / 0.2, 0), (X + 0.15 * distance, vh),
               (X + 0.85 * distance, vh), (X + distance, 0), (X + distance, 0)]
        kt += [s, t1, t2, t2 + 0.5 * t_flight, t4, t5]
        lean_k += [np.deg2rad(2), lean_crouch, np.deg2rad(5), np.deg2rad(8), 0.7 * lean_crouch,
                   np.deg2rad(2)]
        arm_k += [0.0, -arm_back, arm_up, 0.8 * arm_up, np.deg2rad(40), 0.0]
        el_k += [0.25, 0.3, 0.2, 0.3, 0.5, 0.25]
        flights.append((t2, t3, X))
        X += distance
    tk, kt = np.array(tk), np.array(kt)
    zk, xk = np.array(zk, float), np.array(xk, float)
    # strictly increasing key times (the first start may coincide with t=0)
    keep = np.concatenate([[True], np.diff(tk) > 1e-9])
    z = CubicHermiteSpline(tk[keep], zk[keep, 0], zk[keep, 1])(np.clip(t, 0, tk[-1]))
    x = CubicHermiteSpline(tk[keep], xk[keep, 0], xk[keep, 1])(np.clip(t, 0, tk[-1]))
    keep = np.concatenate([[True], np.diff(kt) > 1e-9])
    plan.lean = _keys(t, kt[keep], np.array(lean_k)[keep])
    arm = _keys(t, kt[keep], np.array(arm_k)[keep])
    el = _keys(t, kt[keep], np.array(el_k)[keep])
    plan.shoulder[:, :, 0] = arm[:, None]
    plan.elbow[:] = el[:, None]
    plan.pitch = 0.3 * plan.lean
    plan.head_pitch = -0.5 * plan.lean
    feet_x = np.full(T, x0)
    for t2, t3, Xs in flights:
        feet_x = np.where(t >= t3, Xs + distance, feet_x)
        fl = (t > t2) & (t < t3)
        dt = t - t2
        z = np.where(fl, z_to + v0 * dt - 0.5 * GRAVITY_M_S2 * dt * dt, z)
        tau = np.clip(dt / t_flight, 0, 1)
        feet_x = np.where(fl, Xs + distance * _smooth(tau), feet_x)
        for side in (LEFT, RIGHT):
            plan.planted[fl, side] = False
            plan.in_reach[fl, side] = False
            plan.ankle[fl, side, 2] = (p.ankle_height + (z[fl] - z_to) + tuck * np.sin(np.pi * tau[fl]) ** 2)
    plan.pelvis_xy = centre + x[:, None] * f2
    plan.pelvis_z = z
    for side, lat in ((LEFT, -1.0), (RIGHT, 1.0)):
        plan.ankle[:, side, :2] = centre + feet_x[:, None] * f2 + lat * half_width * r2
    plan.knee_out[:] = 0.25
    return plan


# --------------------------------------------------------------------- kick
def _kick(ctx: _Ctx) -> _Plan:
    p, t, T = ctx.p, ctx.t, ctx.T
    plan = _Plan(T)
    centre, heading = ctx.placement()
    half_width = p.hip_half_width + ctx.uniform("stance_extra_m", 0.0, 0.04)
    fwd, right = _stand(ctx, plan, centre, heading, half_width)
    f2, r2 = fwd[0, :2], right[0, :2]
    plan.relaxed_arms(ctx)
    _breathing(ctx, plan, fwd, right, scale=0.5)
    kick = ctx.choice("kick_leg", ("left", "right"))
    ks = LEFT if kick == "left" else RIGHT
    ss = 1 - ks
    lat_k = -1.0 if ks == LEFT else 1.0
    flex = ctx.deg("kick_hip_flexion_deg", 55.0, 90.0)
    back = ctx.uniform("windup_back_m", 0.15, 0.3)
    windup_h = ctx.uniform("windup_height_m", 0.2, 0.35)
    lean_back = ctx.deg("kick_lean_back_deg", 8.0, 20.0)
    shift = half_width * ctx.uniform("weight_shift_ratio", 0.7, 0.95)
    drop = ctx.uniform("support_knee_drop_m", 0.01, 0.04)
    arm_f = ctx.deg("counter_arm_deg", 30.0, 60.0)
    arm_abd = ctx.deg("arm_out_deg", 20.0, 45.0)
    d = dict(lead=ctx.uniform("lead_in_s", 0.3, 0.7), shift=ctx.uniform("shift_s", 0.3, 0.5),
             wind=ctx.uniform("windup_s", 0.25, 0.4), strike=ctx.uniform("strike_s", 0.15, 0.25),
             hold=ctx.uniform("hold_s", 0.05, 0.15), ret=ctx.uniform("retract_s", 0.35, 0.5),
             back=ctx.uniform("shift_back_s", 0.3, 0.5), rest=ctx.uniform("rest_s", 0.4, 1.0))
    one = d["shift"] + d["wind"] + d["strike"] + d["hold"] + d["ret"] + d["back"]
    starts = _repeat_times(ctx, d["lead"], lambda i: (one, d["rest"]))
    ctx.params["n_kicks"] = len(starts)
    z0 = plan.pelvis_z[0]
    hip_lat = lat_k * p.hip_half_width
    # kick-leg ankle keys in the body frame: (forward, lateral from centre, height)
    tk, ak, sk, zk, lk, ek, yk = [0.0], [], [0.0], [z0], [0.0], [0.0], [0.0]
    ak.append((0.0, lat_k * half_width, p.ankle_height))
    planted = np.ones(T, bool)
    for s in starts:
        t1 = s + d["shift"]
        t2 = t1 + d["wind"]
        t3 = t2 + d["strike"]
        t4 = t3 + d["hold"]
        t5 = t4 + d["ret"]
        t6 = t5 + d["back"]
        hip_z = z0 - drop
        reach = 0.99 * ctx.reach
        strike = (reach * np.sin(flex), hip_lat - lat_k * shift, max(hip_z - reach * np.cos(flex),
                                                                     p.ankle_height + 0.05))
        tk += [s, t1, t1 + 0.3 * d["wind"], t2, t3, t4, t4 + 0.6 * d["ret"], t5, t6]
        ak += [(0.0, lat_k * half_width, p.ankle_height),
               (0.0, lat_k * half_width, p.ankle_height),
               (-0.5 * back, lat_k * half_width, p.ankle_height + 0.5 * windup_h),
               (-back, lat_k * half_width, p.ankle_height + windup_h),
               strike, strike,
               (0.15, lat_k * half_width, p.ankle_height + 0.15),
               (0.0, lat_k * half_width, p.ankle_height),
               (0.0, lat_k * half_width, p.ankle_height)]
        sk += [0.0, shift, shift, shift, shift, shift, shift, shift, 0.0]
        zk += [z0, hip_z, hip_z, hip_z, hip_z, hip_z, hip_z, hip_z, z0]
        lk += [0.0, 0.0, 0.0, 0.0, -lean_back, -lean_back, 0.0, 0.0, 0.0]
        ek += [0.0, 0.3, 0.5, 0.6, 1.0, 1.0, 0.5, 0.2, 0.0]
        yk += [0.0, 0.0, 0.0, 0.0, 1.0, 1.0, 0.3, 0.0, 0.0]
        planted &= ~((t > t1) & (t < t5))
    tk = np.array(tk)
    keep = np.concatenate([[True], np.diff(tk) > 1e-9])
    tk = tk[keep]
    ak = np.array(ak)[keep]
    body = _keys(t, tk, ak)
    sft = _keys(t, tk, np.array(sk)[keep])
    effort = _keys(t, tk, np.array(ek)[keep])
    plan.ankle[:, ks, :2] = centre + body[:, 0:1] * f2 + body[:, 1:2] * r2
    plan.ankle[:, ks, 2] = body[:, 2]
    plan.planted[:, ks] = planted
    plan.in_reach[:, ks] = planted
    # pelvis over the support foot (its side is -lat_k)
    plan.pelvis_xy += (-lat_k * sft)[:, None] * r2
    plan.pelvis_z = np.minimum(plan.pelvis_z, _keys(t, tk, np.array(zk)[keep]))
    plan.lean += _keys(t, tk, np.array(lk)[keep])
    plan.yaw += lat_k * np.deg2rad(10.0) * _keys(t, tk, np.array(yk)[keep])
    # counter-balancing arms: the arm opposite the kicking leg swings forward
    plan.shoulder[:, ss, 0] = arm_f * effort
    plan.shoulder[:, ks, 0] = -0.6 * arm_f * effort
    plan.shoulder[:, :, 1] += (arm_abd * effort)[:, None]
    plan.elbow += (np.deg2rad(25.0) * effort)[:, None]
    plan.knee_out[:] = 0.1
    return plan


# --------------------------------------------------------------------- turn
def _turn(ctx: _Ctx) -> _Plan:
    p, t, T = ctx.p, ctx.t, ctx.T
    plan = _Plan(T)
    centre, heading = ctx.placement()
    half_width = p.hip_half_width + ctx.uniform("stance_extra_m", 0.0, 0.04)
    _stand(ctx, plan, centre, heading, half_width)
    plan.relaxed_arms(ctx)
    angle = ctx.deg("turn_angle_deg", 150.0, 210.0)
    direction = 1.0 if ctx.choice("turn_direction", ("left", "right")) == "left" else -1.0
    t_turn = ctx.uniform("turn_s", 1.6, 2.6)
    step_angle = ctx.deg("step_angle_deg", 35.0, 50.0)
    n_steps = max(3, int(np.ceil(angle / step_angle)) + 1)
    ctx.params["n_steps"] = n_steps
    lift = ctx.uniform("step_lift_m", 0.04, 0.08)
    lead = ctx.uniform("lead_in_s", 0.2, 0.6)
    pause = ctx.uniform("pause_s", 0.5, 1.2)
    lead_twist = ctx.deg("shoulder_lead_deg", 8.0, 15.0)
    swing_frac = ctx.uniform("swing_fraction", 0.55, 0.7)
    starts = _repeat_times(ctx, lead, lambda i: (t_turn, pause))
    ctx.params["n_turns"] = len(starts)
    yaw = np.full(T, heading)
    foot_yaw = np.full((T, 2), heading)
    lift_z = np.zeros((T, 2))
    planted = np.ones((T, 2), bool)
    twist = np.zeros(T)
    shift = np.zeros(T)
    h = heading
    d = direction
    for s in starts:
        yaw = np.where(t >= s, h + d * angle * _ramp(t, s, s + t_turn), yaw)
        twist += d * lead_twist * np.sin(np.pi * np.clip((t - s) / t_turn, 0, 1))
        slot = t_turn / n_steps
        # the foot on the side of the turn opens first
        first = LEFT if d > 0 else RIGHT
        prev = {LEFT: h, RIGHT: h}
        for k in range(n_steps):
            side = first if k % 2 == 0 else 1 - first
            a0, a1 = s + k * slot, s + k * slot + swing_frac * slot
            target = h + d * angle * min(1.0, (k + 1) / (n_steps - 1))
            sw = (t > a0) & (t < a1)
            tau = np.clip((t - a0) / (a1 - a0), 0, 1)
            fy = prev[side] + (target - prev[side]) * _smooth(tau)
            foot_yaw[:, side] = np.where(t >= a0, fy, foot_yaw[:, side])
            lift_z[sw, side] = lift * np.sin(np.pi * tau[sw]) ** 2
            planted[sw, side] = False
            # weight over the other foot while this one swings
            shift += (-1.0 if side == RIGHT else 1.0) * 0.02 * np.sin(np.pi * tau) * sw
            prev[side] = target
        h = h + d * angle
        d = d * (1.0 if ctx.rng.uniform() < 0.5 else -1.0)
    fwd, right = _heading_vectors(yaw)
    for side, lat in ((LEFT, -1.0), (RIGHT, 1.0)):
        _, r_f = _heading_vectors(foot_yaw[:, side])
        plan.ankle[:, side, :2] = centre + lat * half_width * r_f[:, :2]
        plan.ankle[:, side, 2] = p.ankle_height + lift_z[:, side]
    plan.planted = planted
    plan.in_reach[:] = True
    plan.yaw = yaw
    plan.twist = twist
    plan.pelvis_xy = centre + (-shift)[:, None] * right[:, :2]
    plan.pelvis_z[:] -= 0.01
    plan.lean[:] = np.deg2rad(3.0)
    plan.shoulder[:, :, 0] = np.deg2rad(8.0) * np.sin(2 * np.pi * 0.8 * t)[:, None] * np.array([1, -1])
    return plan


# --------------------------------------------------------------------- wave
def _wave(ctx: _Ctx) -> _Plan:
    p, t, T = ctx.p, ctx.t, ctx.T
    plan = _Plan(T)
    centre, heading = ctx.placement()
    half_width = p.hip_half_width + ctx.uniform("stance_extra_m", 0.0, 0.06)
    fwd, right = _stand(ctx, plan, centre, heading, half_width)
    plan.relaxed_arms(ctx)
    _breathing(ctx, plan, fwd, right)
    arm = ctx.choice("wave_arm", ("left", "right"))
    a = LEFT if arm == "left" else RIGHT
    abd = ctx.deg("raise_abduction_deg", 95.0, 125.0)
    flex = ctx.deg("raise_flexion_deg", 0.0, 20.0)
    ext_rot = ctx.deg("external_rotation_deg", 80.0, 95.0)
    elbow = ctx.deg("raised_elbow_deg", 70.0, 100.0)
    freq = ctx.uniform("wave_hz", 1.5, 2.5)
    amp = ctx.deg("wave_amplitude_deg", 15.0, 30.0)
    t_raise = ctx.uniform("raise_s", 0.4, 0.8)
    t_wave = ctx.uniform("wave_s", 1.5, 3.0)
    t_lower = ctx.uniform("lower_s", 0.5, 0.8)
    rest = ctx.uniform("rest_s", 0.5, 1.5)
    lead = ctx.uniform("lead_in_s", 0.1, 0.5)
    tilt = ctx.deg("head_tilt_deg", -8.0, 8.0)
    starts = _repeat_times(ctx, lead, lambda i: (t_raise + t_wave + t_lower, rest))
    ctx.params["n_waves"] = len(starts)
    up = np.zeros(T)
    waving = np.zeros(T)
    for s in starts:
        e1, e2, e3 = s + t_raise, s + t_raise + t_wave, s + t_raise + t_wave + t_lower
        up = np.maximum(up, _ramp(t, s, e1) * (1 - _ramp(t, e2, e3)))
        waving += ((t > e1 - 0.2) & (t < e2 + 0.2)) * np.sin(2 * np.pi * freq * (t - e1)) \
            * np.clip(np.minimum(t - (e1 - 0.2), (e2 + 0.2) - t) / 0.2, 0, 1)
    base = plan.shoulder[:, a].copy()
    plan.shoulder[:, a, 0] = base[:, 0] + up * flex
    plan.shoulder[:, a, 1] = base[:, 1] + up * (abd - base[:, 1])
    plan.shoulder[:, a, 2] = -up * ext_rot
    plan.elbow[:, a] = plan.elbow[:, a] + up * (elbow - plan.elbow[:, a]) + amp * waving * up
    plan.head_roll += up * tilt
    # weight slightly on the other leg while waving
    lat = -1.0 if a == LEFT else 1.0
    plan.pelvis_xy += (-lat * 0.02 * up)[:, None] * right[:, :2]
    return plan


# ------------------------------------------------------------------- crouch
def _crouch(ctx: _Ctx) -> _Plan:
    p, t, T = ctx.p, ctx.t, ctx.T
    plan = _Plan(T)
    centre, heading = ctx.placement()
    half_width = p.hip_half_width + ctx.uniform("stance_extra_m", 0.03, 0.10)
    fwd, right = _stand(ctx, plan, centre, heading, half_width)
    plan.relaxed_arms(ctx)
    _breathing(ctx, plan, fwd, right, scale=0.5)
    depth = ctx.leg * ctx.uniform("depth_ratio", 0.30, 0.50)
    hips_back = ctx.uniform("hips_back_m", 0.05, 0.15)
    lean = ctx.deg("bottom_lean_deg", 25.0, 45.0)
    arms = ctx.deg("arms_forward_deg", 30.0, 80.0)
    t_down = ctx.uniform("down_s", 0.8, 1.4)
    t_hold = ctx.uniform("hold_s", 0.3, 1.0)
    t_up = ctx.uniform("up_s", 0.8, 1.2)
    rest = ctx.uniform("rest_s", 0.4, 1.2)
    lead = ctx.uniform("lead_in_s", 0.1, 0.5)
    knees_out = ctx.uniform("knees_out", 0.1, 0.35)
    starts = _repeat_times(ctx, lead, lambda i: (t_down + t_hold + t_up, rest))
    ctx.params["n_crouches"] = len(starts)
    c = np.zeros(T)
    for s in starts:
        c = np.maximum(c, _ramp(t, s, s + t_down) * (1 - _ramp(t, s + t_down + t_hold,
                                                               s + t_down + t_hold + t_up)))
    plan.pelvis_z = plan.pelvis_z - depth * c
    plan.pelvis_xy -= (hips_back * c)[:, None] * fwd[:, :2]
    plan.lean += lean * c
    plan.pitch = 0.4 * lean * c
    plan.head_pitch += -0.6 * lean * c
    plan.shoulder[:, :, 0] += (arms * c)[:, None]
    plan.elbow += (np.deg2rad(15.0) * c)[:, None]
    plan.knee_out[:] = knees_out
    return plan


# --------------------------------------------------------------------- idle
def _idle(ctx: _Ctx) -> _Plan:
    p, T = ctx.p, ctx.T
    plan = _Plan(T)
    centre, heading = ctx.placement()
    half_width = p.hip_half_width + ctx.uniform("stance_extra_m", 0.0, 0.06)
    fwd, right = _stand(ctx, plan, centre, heading, half_width)
    plan.relaxed_arms(ctx)
    _breathing(ctx, plan, fwd, right, scale=2.0)
    t = ctx.t
    f = ctx.uniform("arm_drift_hz", 0.1, 0.3)
    plan.shoulder[:, LEFT, 0] += np.deg2rad(5.0) * np.sin(2 * np.pi * f * t)
    plan.shoulder[:, RIGHT, 0] += np.deg2rad(5.0) * np.sin(2 * np.pi * f * t + 1.3)
    return plan


_BUILDERS = {"walk": _walk, "run": _run, "jump": _jump, "kick": _kick, "turn": _turn,
             "wave": _wave, "crouch": _crouch, "idle": _idle}


# ---------------------------------------------------------------------- API
def _check_args(name, n_frames, fps):
    if name not in _BUILDERS:
        raise InputError("motion", f"one of {list(MOTIONS)}", repr(name))
    if isinstance(n_frames, bool) or not isinstance(n_frames, (int, np.integer)) or n_frames <= 0:
        raise InputError("n_frames", "a positive integer", repr(n_frames))
    if isinstance(fps, bool) or not isinstance(fps, (int, float, np.integer, np.floating)) \
            or not np.isfinite(fps) or fps <= 0:
        raise InputError("fps", "a positive frame rate", repr(fps))


def synthesize_motion(name: str, proportions: BodyProportions, n_frames: int, fps: float,
                      rng: np.random.Generator | int | None = None, observer=None) -> Motion:
    """Generate a motion and its ground truth (angles, foot contacts, parameters).

    Parameters
    ----------
    name : str
        One of :data:`MOTIONS`.
    proportions : BodyProportions
        Segment lengths of the person, metres.
    n_frames : int
        Number of frames, > 0.
    fps : float
        Frames per second, > 0.
    rng : numpy.random.Generator or int or None
        Source of the per-scene variation (speed, stride, amplitudes, phase,
        heading, position, which arm waves or leg kicks).
    observer : Observer, optional
        Receives one ``joints3d`` report per frame (``name="motion/<name>"``).

    Returns
    -------
    Motion

    Raises
    ------
    InputError
        Unknown motion name, or non-positive ``n_frames`` or ``fps``.
    """
    _check_args(name, n_frames, fps)
    if not isinstance(proportions, BodyProportions):
        raise InputError("proportions", "a BodyProportions", type(proportions).__name__)
    rng = np.random.default_rng(rng)
    ctx = _Ctx(proportions, int(n_frames), float(fps), rng)
    plan = _BUILDERS[name](ctx)
    motion = _finish(ctx, plan, name)
    obs = as_observer(observer)
    for i, frame in enumerate(motion.joints):
        obs.report("joints3d", joints=frame, name=f"motion/{name}", skeleton=SKELETON_14, frame=i)
    return motion


def generate_motion(name: str, proportions: BodyProportions, n_frames: int, fps: float,
                    rng: np.random.Generator | int | None = None, observer=None) -> np.ndarray:
    """Joint positions of a procedural motion.

    Same arguments as :func:`synthesize_motion`.

    Returns
    -------
    ndarray of shape (n_frames, 14, 3)
        Metres, world, z up, ground z = 0, order of ``SKELETON_14.joint_names``.

    Examples
    --------
    >>> from toolkit.anthropometry.proportions import BodyProportions
    >>> j = generate_motion("walk", BodyProportions.from_height(1.75), 50, 25.0, rng=0)
    >>> j.shape
    (50, 14, 3)
    """
    return synthesize_motion(name, proportions, n_frames, fps, rng, observer).joints
