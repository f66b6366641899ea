"""The functional calibration trial (``rom``) of motion-capture labs.

The performer stands still, then moves each joint through its range in
turn, as labs record for functional joint centres (Camomilla et al. 2006,
"An optimized protocol for hip joint centre determination using the
functional method", J. Biomech. 39(6): the *star-arc*: flexion-extension
and abduction rays from the neutral hip, then a circumduction arc).  Per
side, in a seeded order of sides:

* leg block: weight shifted onto the other foot, the foot lifted (hip and
  knee flexed together so the ankle rises vertically), the hip moved along
  the star's five rays (flexion, flexion-abduction, abduction,
  extension-abduction, extension) and round a circumduction arc, the knee
  flexed twice, the ankle dorsi- and plantar-flexed twice with the foot off
  the ground; the foot put down where it was lifted;
* arm block: shoulder flexion, shoulder abduction, a shoulder circle, then
  elbow flexion twice with the upper arm forward.

Amplitudes, durations and the order of the sides are drawn from ``rng`` and
recorded in :attr:`Motion.params`.  The whole trial takes about
:data:`NATURAL_DURATION_S` seconds at its natural pace; a shorter clip plays
it faster (so every joint is always moved), a longer one at most
:data:`MAX_SLOWDOWN` times slower, then the performer stands still.

The ankle angle is not part of the 14-joint skeleton: it is returned in
:attr:`Motion.ankle` (radians, > 0 lifts the toes) for the marker feet
(:mod:`toolkit.markers.marker_sets`).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from toolkit.motion.actions import _breathing, _stand
from toolkit.motion.kinematics import LEFT, RIGHT, forward_kinematics
from toolkit.motion.planning import Motion, _Ctx, _finish, _keys, _Plan, _ramp

__all__ = ["NATURAL_DURATION_S", "MAX_SLOWDOWN", "ROM_STAR_RAYS_DEG", "rom_motion"]

#: Directions of the hip star's rays, degrees from flexion towards abduction (180 = extension).
ROM_STAR_RAYS_DEG = (0.0, 45.0, 90.0, 135.0, 180.0)
#: Natural-pace durations of the movements, seconds (each drawn within +-20 %).
_DUR = {"prep": 0.35, "ray": 0.9, "circ": 2.2, "knee": 1.8, "ankle": 1.6, "sh_flex": 1.4, "sh_abd": 1.4,
        "sh_circ": 2.2, "elbow": 1.8, "rest": 0.3}
#: Natural duration of the whole trial, seconds (two legs and two arms).
NATURAL_DURATION_S = 2 * (2 * _DUR["prep"] + 5 * _DUR["ray"] + _DUR["circ"] + _DUR["knee"] + _DUR["ankle"]
                          + 3 * _DUR["rest"] + _DUR["sh_flex"] + _DUR["sh_abd"] + _DUR["sh_circ"]
                          + _DUR["elbow"] + 4 * _DUR["rest"])
#: Longest slowdown of the trial in a long clip.
MAX_SLOWDOWN = 1.5


def _out_back(s):
    """0 -> 1 -> 0 on s in [0, 1] (minimum-jerk out, and back)."""
    s = np.clip(s, 0.0, 1.0)
    return np.where(s < 0.5, _ramp(s, 0.0, 0.5), 1.0 - _ramp(s, 0.5, 1.0))


def _window(t, t0, t1):
    """Normalised time in [t0, t1] (NaN outside)."""
    s = (t - t0) / max(t1 - t0, 1e-9)
    return np.where((s >= 0) & (s <= 1), s, np.nan)


def _schedule(ctx: _Ctx):
    """Movement list [(name, side, duration)] in trial order and the time scale."""
    order = ctx.choice("first_side", ("right", "left"))
    sides = (RIGHT, LEFT) if order == "right" else (LEFT, RIGHT)
    jit = lambda: float(ctx.rng.uniform(0.8, 1.2))  # noqa: E731
    items = []
    for side in sides:
        items += [("leg_prep", side, _DUR["prep"] * jit())]
        items += [(f"ray{k}", side, _DUR["ray"] * jit()) for k in range(len(ROM_STAR_RAYS_DEG))]
        items += [("circ", side, _DUR["circ"] * jit()), ("rest", side, _DUR["rest"]),
                  ("knee", side, _DUR["knee"] * jit()), ("rest", side, _DUR["rest"]),
                  ("ankle", side, _DUR["ankle"] * jit()), ("leg_done", side, _DUR["prep"] * jit()),
                  ("rest", side, _DUR["rest"])]
    for side in sides:
        items += [("sh_flex", side, _DUR["sh_flex"] * jit()), ("rest", side, _DUR["rest"]),
                  ("sh_abd", side, _DUR["sh_abd"] * jit()), ("rest", side, _DUR["rest"]),
                  ("sh_circ", side, _DUR["sh_circ"] * jit()), ("rest", side, _DUR["rest"]),
                  ("elbow", side, _DUR["elbow"] * jit()), ("rest", side, _DUR["rest"])]
    lead = ctx.uniform("lead_in_s", 0.2, 0.6)
    total = lead + sum(d for _, _, d in items)
    scale = min(MAX_SLOWDOWN, ctx.duration / total) if ctx.duration > 0 else 1.0
    ctx.params["time_scale"] = float(scale)
    t0, out = lead * scale, []
    for name, side, d in items:
        out.append((name, side, t0, t0 + d * scale))
        t0 += d * scale
    return out, scale


def rom_motion(ctx: _Ctx) -> Motion:
    """Build the trial (see the module docstring); returns the finished :class:`Motion`."""
    p, t, T = ctx.p, ctx.t, ctx.T
    plan = _Plan(T)
    centre, heading = ctx.placement()
    fwd, right = _stand(ctx, plan, centre, heading, p.hip_half_width)
    plan.relaxed_arms(ctx)
    _breathing(ctx, plan, fwd, right, scale=0.5)
    items, _ = _schedule(ctx)
    sname = {LEFT: "l", RIGHT: "r"}
    amp = {}
    for side in (LEFT, RIGHT):
        s = sname[side]
        amp[side] = dict(
            lift=ctx.deg(f"{s}_lift_deg", 14.0, 20.0), flex=ctx.deg(f"{s}_hip_flexion_deg", 40.0, 60.0),
            abd=ctx.deg(f"{s}_hip_abduction_deg", 25.0, 40.0), ext=ctx.deg(f"{s}_hip_extension_deg", 15.0, 25.0),
            circ_c=ctx.deg(f"{s}_circ_centre_deg", 18.0, 24.0), circ_r=ctx.deg(f"{s}_circ_radius_deg", 14.0, 18.0),
            knee=ctx.deg(f"{s}_knee_flexion_deg", 80.0, 100.0), dorsi=ctx.deg(f"{s}_dorsiflexion_deg", 15.0, 25.0),
            plantar=ctx.deg(f"{s}_plantarflexion_deg", 25.0, 40.0),
            sh_flex=ctx.deg(f"{s}_shoulder_flexion_deg", 120.0, 160.0),
            sh_abd=ctx.deg(f"{s}_shoulder_abduction_deg", 85.0, 115.0),
            sh_circ=ctx.deg(f"{s}_shoulder_circle_deg", 30.0, 40.0),
            elbow=ctx.deg(f"{s}_elbow_flexion_deg", 115.0, 140.0),
            shift=ctx.uniform(f"{s}_weight_shift_m", 0.03, 0.05))
    lift = np.zeros((T, 2))        # 0..1: foot lifted
    hip_d = np.zeros((T, 2, 3))    # hip flexion/abduction added on the lifted leg
    knee_d = np.zeros((T, 2))
    ankle = np.zeros((T, 2))
    shift = np.zeros(T)            # pelvis shift towards the stance side, metres (signed along right)
    for name, side, a, b in items:
        A = amp[side]
        lat = -1.0 if side == LEFT else 1.0
        if name == "leg_prep":
            m = (a + b) / 2
            shift -= lat * A["shift"] * _ramp(t, a, m)
            lift[:, side] = np.maximum(lift[:, side], _ramp(t, m, b))
            plan.planted[t >= m, side] = False
        elif name == "leg_done":
            m = (a + b) / 2
            lift[:, side] = np.where(t >= a, 1.0 - _ramp(t, a, m), lift[:, side])
            shift += lat * A["shift"] * _ramp(t, m, b)
            plan.planted[t > m, side] = True
        elif name.startswith("ray"):
            ray = np.deg2rad(ROM_STAR_RAYS_DEG[int(name[3:])])
            reach = A["flex"] if ray < np.pi / 2 - 1e-9 else A["ext"] if ray > np.pi / 2 + 1e-9 else A["abd"]
            e = np.nan_to_num(_out_back(_window(t, a, b)))
            hip_d[:, side, 0] += e * reach * np.cos(ray)
            hip_d[:, side, 1] += e * min(reach, A["abd"]) * np.sin(ray)
        elif name == "circ":
            s_ = _window(t, a, b)
            env = np.nan_to_num(np.minimum(_ramp(s_, 0.0, 0.15), 1.0 - _ramp(s_, 0.85, 1.0)))
            th = 2 * np.pi * np.clip((np.nan_to_num(s_) - 0.15) / 0.7, 0.0, 1.0)
            hip_d[:, side, 0] += env * (A["circ_c"] + A["circ_r"] * np.cos(th))
            hip_d[:, side, 1] += env * (A["circ_c"] + A["circ_r"] * np.sin(th))
        elif name == "knee":
            s_ = _window(t, a, b)
            hold = np.nan_to_num(np.minimum(_ramp(s_, 0.0, 0.15), 1.0 - _ramp(s_, 0.85, 1.0)))
            hip_d[:, side, 0] += hold * np.deg2rad(25.0)
            knee_d[:, side] += np.nan_to_num(_out_back(np.mod(np.clip((s_ - 0.1) / 0.4, 0, 2), 1.0))
                                             * ((s_ > 0.1) & (s_ < 0.9))) * A["knee"]
        elif name == "ankle":
            s_ = _window(t, a, b)
            hold = np.nan_to_num(np.minimum(_ramp(s_, 0.0, 0.15), 1.0 - _ramp(s_, 0.85, 1.0)))
            hip_d[:, side, 0] += hold * np.deg2rad(30.0)
            knee_d[:, side] += hold * np.deg2rad(45.0)
            ok = np.isfinite(s_)
            keys = np.linspace(0.15, 0.85, 6)
            ankle[ok, side] = _keys(s_[ok], keys, [0.0, A["dorsi"], -A["plantar"], A["dorsi"], -A["plantar"], 0.0])
        elif name in ("sh_flex", "sh_abd", "elbow", "sh_circ"):
            s_ = _window(t, a, b)
            if name == "sh_flex":
                plan.shoulder[:, side, 0] += np.nan_to_num(_out_back(s_)) * A["sh_flex"]
            elif name == "sh_abd":
                plan.shoulder[:, side, 1] += np.nan_to_num(_out_back(s_)) * (A["sh_abd"] - plan.shoulder[:, side, 1])
            elif name == "sh_circ":
                env = np.nan_to_num(np.minimum(_ramp(s_, 0.0, 0.15), 1.0 - _ramp(s_, 0.85, 1.0)))
                th = 2 * np.pi * np.clip((np.nan_to_num(s_) - 0.15) / 0.7, 0.0, 1.0)
                c = np.deg2rad(50.0)
                plan.shoulder[:, side, 0] += env * (c + A["sh_circ"] * np.cos(th))
                plan.shoulder[:, side, 1] += env * (c + A["sh_circ"] * np.sin(th))
            else:
                hold = np.nan_to_num(np.minimum(_ramp(s_, 0.0, 0.15), 1.0 - _ramp(s_, 0.85, 1.0)))
                plan.shoulder[:, side, 0] += hold * np.deg2rad(40.0)
                plan.elbow[:, side] += np.nan_to_num(_out_back(np.mod(np.clip((s_ - 0.1) / 0.4, 0, 2), 1.0))
                                                     * ((s_ > 0.1) & (s_ < 0.9))) * (A["elbow"] - plan.elbow[:, side])
    plan.pelvis_xy += shift[:, None] * right[:, :2]
    plan.in_reach[:] = plan.planted  # a lifted foot's target (where it stood) does not hold the pelvis down
    motion = _finish(ctx, plan, "rom")
    # the lifted legs: the IK angles that keep the foot where it stood, plus the lift and the movements
    pose = motion.pose
    hip, knee = pose.hip.copy(), pose.knee.copy()
    for side in (LEFT, RIGHT):
        up = lift[:, side] * amp[side]["lift"]
        hip[:, side, 0] += up + lift[:, side] * hip_d[:, side, 0]
        hip[:, side, 1] += lift[:, side] * hip_d[:, side, 1]
        knee[:, side] += 2.0 * up + lift[:, side] * knee_d[:, side]
    pose = replace(pose, hip=hip, knee=knee)
    joints = forward_kinematics(p, pose)
    return replace(motion, joints=joints, pose=pose, ankle=ankle * lift)
