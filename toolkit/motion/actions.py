"""In-place motions (:mod:`toolkit.motion.library`): jump, kick, turn, wave, crouch, idle."""

from __future__ import annotations

import numpy as np
from scipy.interpolate import CubicHermiteSpline

from toolkit.motion.kinematics import LEFT, RIGHT
from toolkit.motion.planning import _Ctx, _heading_vectors, _keys, _Plan, _ramp, _smooth

#: Standard gravity, m/s^2 (ballistic flight of jumps).
GRAVITY_M_S2 = 9.81
#: Safety margin below the reach limit used for the planned heights of
#: jumps (takeoff), metres.
TAKEOFF_MARGIN_M = 0.02


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

