"""Walking and running (:mod:`toolkit.motion.library`): a gait plan of steps along a line or a circle."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.interpolate import PchipInterpolator

from toolkit.motion.kinematics import LEFT, RIGHT
from toolkit.motion.planning import _bump, _Ctx, _heading_vectors, _heel_off, _Plan, _smooth

#: Step frequency (steps per second) range of walking; mean about 1.8 Hz
#: (typical adult cadence 100-115 steps/min).
WALK_CADENCE_HZ = (1.65, 1.95)
#: Step frequency range of running; mean about 2.8 Hz (160-180 steps/min).
RUN_CADENCE_HZ = (2.6, 3.0)
#: A walk or run goes along a straight line only if it stays within this
#: distance of the origin; otherwise it follows a circle, metres.
LINE_HALF_LENGTH_M = 3.0
#: A walk or run kept within ``area_m`` of its centre (:func:`_loop_path`) turns round on
#: semicircles of this share of ``area_m``; the straight stretches between them take the rest.
LOOP_TURN_SHARE = 0.5
#: Fastest turn (radians per second) of the pelvis on a loop's semicircles: the person slows down
#: there (shorter steps at the same cadence) when the straight stretches' speed would turn faster.
LOOP_TURN_RATE = 3.0
#: Samples of the drawn path checked against ``area_m``.
AREA_CHECK_SAMPLES = 200
#: Normalised horizontal speed of the ankle at the start of swing (Hermite
#: slope; 0 = starts at rest, 1 = starts at the mean swing speed).
SWING_START_SLOPE = 0.8


@dataclass(frozen=True)
class _GaitParams:
    """The drawn parameters of one walk or run (lengths in metres, angles in radians)."""

    cadence: float
    step: float
    duty: float
    heel_off_at: float
    ahead: float
    knee_stance: float
    knee_swing: float
    alpha_max: float
    lift: float
    drop: float
    bob: float
    sway: float
    lean0: float
    arm_swing: float
    elbow0: float
    arm_rot: float
    pelvis_rot: float
    thorax_rot: float
    pelvis_roll: float
    half_width: float
    phase0: float


def _gait_params(ctx: _Ctx, running: bool) -> _GaitParams:
    """Draw the gait's parameters (recorded in ``ctx.params``), in a fixed order.

    Parameters
    ----------
    ctx : _Ctx
    running : bool
        Running ranges, else walking ranges.

    Returns
    -------
    _GaitParams
    """
    p = ctx.p
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
    return _GaitParams(cadence, step, duty, heel_off_at, ahead, knee_stance, knee_swing, alpha_max, lift, drop, bob,
                       sway, lean0, arm_swing, elbow0, arm_rot, pelvis_rot, thorax_rot, pelvis_roll, half_width,
                       phase0)


def _gait_path(ctx: _Ctx, speed: float, running: bool):
    """The path of the pelvis: a line through the origin when the travel fits, else a circle around it.

    Parameters
    ----------
    ctx : _Ctx
        Draws the path's parameters (recorded in ``ctx.params``).
    speed : float
        Walking speed, metres per second.
    running : bool
        Allows a wider circle.

    Returns
    -------
    callable
        ``path(s)``: arc length ``s`` (N,) metres -> positions (N, 2) metres and headings (N,) radians.
    """
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
    if ctx.area_m is not None:
        pos, _ = path(np.linspace(0.0, travel, AREA_CHECK_SAMPLES))
        if np.max(np.linalg.norm(pos - pos.mean(axis=0), axis=1)) > ctx.area_m:
            path = _loop_path(ctx, heading0, speed)
    return path


def _loop_path(ctx: _Ctx, heading0: float, speed: float):
    """A closed loop within ``ctx.area_m`` of the origin: two straight stretches joined by semicircles.

    The loop (a stadium) has turns of radius ``r = LOOP_TURN_SHARE * area_m`` and straight stretches
    of length ``2 (area_m - r)``; the pelvis starts at the apex of one turn, heading ``heading0``
    (across the stretches), and goes round the loop, counter-clockwise or clockwise (drawn:
    ``loop_direction``), as often as the sequence lasts.  So the pelvis stays within ``area_m`` of the
    origin along the stretches and within ``r`` across them, whatever the length of the sequence.
    On the straight stretches the pelvis moves at ``speed``; on the turns at most at
    ``LOOP_TURN_RATE * r`` (a person turning round on a small circle slows down).

    Parameters
    ----------
    ctx : _Ctx
        ``area_m`` set; draws the direction (recorded in ``ctx.params``, with ``path = "loop"``).
    heading0 : float
        Heading at arc length 0, radians.
    speed : float
        Speed on the straight stretches, metres per second.

    Returns
    -------
    callable
        ``path(s)``: ``s`` (N,) = ``speed`` times the time, metres (any real value: the loop repeats) ->
        positions (N, 2) metres and headings (N,) radians, continuous (one turn adds 2 pi).
    """
    ctx.params["path"] = "loop"
    sign = 1.0 if ctx.choice("loop_direction", ("ccw", "cw")) == "ccw" else -1.0
    r = LOOP_TURN_SHARE * ctx.area_m
    a = ctx.area_m - r                                    # half the straight stretch
    fwd0 = np.array([-np.sin(heading0), np.cos(heading0)])
    along = sign * np.array([fwd0[1], -fwd0[0]])          # the stretches' direction; the start at +along
    lengths = np.array([0.5 * np.pi * r, 2 * a, np.pi * r, 2 * a, 0.5 * np.pi * r])
    ends = np.cumsum(lengths)
    turn_speed = min(speed, LOOP_TURN_RATE * r)
    durations = lengths / np.array([turn_speed, speed, turn_speed, speed, turn_speed])
    t_ends = np.r_[0.0, np.cumsum(durations)]

    def path(s):
        laps, t = np.divmod(np.asarray(s, float) / speed, t_ends[-1])
        u = np.interp(t, t_ends, np.r_[0.0, ends])      # arc length within the lap
        x, y, turn = np.empty_like(u), np.empty_like(u), np.empty_like(u)
        first, top, left, bottom, last = (u < ends[0], (u >= ends[0]) & (u < ends[1]),
                                          (u >= ends[1]) & (u < ends[2]), (u >= ends[2]) & (u < ends[3]),
                                          u >= ends[3])
        # the turn at +along (first and last quarter), the stretch back, the turn at -along, the stretch out
        phi = u / r
        x[first], y[first], turn[first] = a + r * np.cos(phi[first]), r * np.sin(phi[first]), phi[first]
        x[top], y[top], turn[top] = a - (u[top] - ends[0]), r, 0.5 * np.pi
        phi = 0.5 * np.pi + (u - ends[1]) / r
        x[left], y[left], turn[left] = -a + r * np.cos(phi[left]), r * np.sin(phi[left]), phi[left]
        x[bottom], y[bottom], turn[bottom] = -a + (u[bottom] - ends[2]), -r, 1.5 * np.pi
        phi = 1.5 * np.pi + (u - ends[3]) / r
        x[last], y[last], turn[last] = a + r * np.cos(phi[last]), r * np.sin(phi[last]), phi[last]
        pos = x[:, None] * along[None] + y[:, None] * fwd0[None]
        return pos, heading0 + sign * (turn + 2 * np.pi * laps)
    return path


def _plan_foot(ctx: _Ctx, plan: _Plan, side: int, off: float, lat: float, g: _GaitParams, path, phase: np.ndarray,
               mid: float, speed: float, running: bool) -> None:
    """Plan one foot: footprints along the path, the ankle through stance, heel-off and swing, the knee's flexion.

    Parameters
    ----------
    ctx : _Ctx
        Draws the footprints' jitter.
    plan : _Plan
        Its ``ankle``, ``planted``, ``in_reach`` and ``min_knee`` of ``side`` are written.
    side : int
        ``LEFT`` or ``RIGHT``.
    off : float
        Phase offset of this foot, strides.
    lat : float
        -1 for the left foot, +1 for the right.
    g : _GaitParams
    path : callable
        From :func:`_gait_path`.
    phase : ndarray of shape (T,)
        Stride phase of each frame.
    mid : float
        Fraction of a stride after contact when the pelvis passes over the ankle.
    speed : float
        Metres per second.
    running : bool
    """
    T = ctx.T
    f = g.cadence / 2.0                      # strides per second
    duty, heel_off_at, alpha_max = g.duty, g.heel_off_at, g.alpha_max
    ah = ctx.p.ankle_height
    dx_max, dz_max = _heel_off(ctx, alpha_max)
    u = phase - off
    k = np.floor(u).astype(int)
    local = u - k
    ks = np.arange(k.min() - 1, k.max() + 3)
    t_fp = (ks + mid + off - g.phase0) / f
    Pf, psif = path(speed * t_fp)
    fwd_f, right_f = _heading_vectors(psif)
    jitter = np.clip(ctx.rng.normal(0.0, 0.008, (len(ks), 2)), -0.02, 0.02)
    fp = Pf + lat * g.half_width * right_f[:, :2] + jitter
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
    sw_z = ah + dz_max * (1 - _smooth(2 * tau)) + g.lift * _bump(tau)
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
        keys_k = [np.deg2rad(15), g.knee_stance, np.deg2rad(25), g.knee_swing, np.deg2rad(20),
                  np.deg2rad(15)]
    else:
        keys_u = [0.0, 0.12, heel_off_at, duty, duty + 0.3 * (1 - duty),
                  duty + 0.85 * (1 - duty), 1.0]
        keys_k = [np.deg2rad(5), g.knee_stance, np.deg2rad(5), np.deg2rad(35), g.knee_swing,
                  np.deg2rad(5), np.deg2rad(5)]
    plan.min_knee[:, side] = PchipInterpolator(keys_u, keys_k)(local)


def _plan_trunk(ctx: _Ctx, plan: _Plan, g: _GaitParams, P: np.ndarray, psi: np.ndarray, right: np.ndarray,
                phase: np.ndarray, mid: float, running: bool) -> None:
    """Plan the pelvis, trunk, head and arms: sway, bob, rotation and lean with the stride, arms swinging opposite.

    Parameters
    ----------
    ctx : _Ctx
    plan : _Plan
        Its pelvis, trunk, head, shoulder and elbow fields are written.
    g : _GaitParams
    P : ndarray of shape (T, 2)
        Pelvis path, metres.
    psi : ndarray of shape (T,)
        Heading, radians.
    right : ndarray of shape (T, 3)
        Right of the heading.
    phase : ndarray of shape (T,)
        Stride phase.
    mid : float
    running : bool
    """
    w = 2 * np.pi
    left_dir = -right[:, :2]
    plan.pelvis_xy = P + (g.sway * np.cos(w * (phase - mid)))[:, None] * left_dir
    plan.pelvis_z = ctx.standing_height(0.0) - g.drop + g.bob * np.cos(2 * w * (phase - mid))
    plan.yaw = psi - g.pelvis_rot * np.cos(w * phase)
    plan.roll = g.pelvis_roll * np.cos(w * (phase - mid))
    plan.pitch[:] = np.deg2rad(3.0)
    plan.lean = g.lean0 + 0.25 * g.lean0 * np.cos(2 * w * (phase - mid))
    plan.twist = (g.pelvis_rot + g.thorax_rot) * np.cos(w * phase)
    plan.head_pitch = -0.6 * plan.lean
    swing_arm = g.arm_swing * np.cos(w * (phase - 0.05))
    plan.shoulder[:, LEFT, 0] = -swing_arm + (np.deg2rad(5.0) if running else 0.0)
    plan.shoulder[:, RIGHT, 0] = swing_arm + (np.deg2rad(5.0) if running else 0.0)
    plan.shoulder[:, :, 1] = np.deg2rad(8.0)
    plan.shoulder[:, :, 2] = g.arm_rot
    plan.elbow[:, LEFT] = g.elbow0 + 0.4 * np.maximum(-swing_arm, 0)
    plan.elbow[:, RIGHT] = g.elbow0 + 0.4 * np.maximum(swing_arm, 0)


def _gait(ctx: _Ctx, running: bool) -> _Plan:
    """A walk or a run: parameters, path, the two feet, then pelvis, trunk and arms.

    Parameters
    ----------
    ctx : _Ctx
    running : bool

    Returns
    -------
    _Plan
    """
    t, T = ctx.t, ctx.T
    g = _gait_params(ctx, running)
    f = g.cadence / 2.0                      # strides per second
    speed = g.step * g.cadence
    # the ankle lands ``ahead * step`` in front of the pelvis; the pelvis passes
    # over it ``mid`` of a stride after contact
    mid = g.ahead * g.step / (2 * g.step)
    ctx.params["speed_m_s"] = speed
    path = _gait_path(ctx, speed, running)
    s_t = speed * t
    P, psi = path(s_t)
    fwd, right = _heading_vectors(psi)
    phase = f * t + g.phase0

    plan = _Plan(T)
    for side, off, lat in ((LEFT, 0.0, -1.0), (RIGHT, 0.5, 1.0)):
        _plan_foot(ctx, plan, side, off, lat, g, path, phase, mid, speed, running)
    _plan_trunk(ctx, plan, g, P, psi, right, phase, mid, running)
    return plan


def _walk(ctx):
    return _gait(ctx, running=False)


def _run(ctx):
    return _gait(ctx, running=True)

