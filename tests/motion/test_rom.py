"""The functional calibration trial ``rom``: every joint moved through its range, in turn, seeded."""

from __future__ import annotations

import numpy as np
import pytest

from toolkit.anthropometry.proportions import BodyProportions
from toolkit.motion import inverse_kinematics, synthesize_motion
from toolkit.motion.rom import NATURAL_DURATION_S
from toolkit.skeleton import SKELETON_14

J = {n: i for i, n in enumerate(SKELETON_14.joint_names)}
#: Smallest range (max - min over the trial) each joint must go through, degrees: the low ends
#: of the drawn amplitudes (hip flexion 40 + extension 15, abduction 25, knee 80, elbow 115 less the
#: relaxed 20, shoulder flexion 120, abduction 85 less the relaxed 12), less 5 degrees.
MIN_RANGE_DEG = {"hip_flexion": 50.0, "hip_abduction": 20.0, "knee": 75.0, "shoulder_flexion": 115.0,
                 "shoulder_abduction": 68.0, "elbow": 90.0}
#: A joint counts as moving when it is this far from its value at the start, degrees.
MOVING_DEG = 8.0


def _angle(a, b, c):
    """Angle at b between b->a and b->c, degrees (T,)."""
    u, v = a - b, c - b
    cos = np.sum(u * v, -1) / np.linalg.norm(u, axis=-1) / np.linalg.norm(v, axis=-1)
    return np.degrees(np.arccos(np.clip(cos, -1, 1)))


def _joint_angles(joints):
    """Angles measured from the joints alone (IK for the hips and shoulders), degrees, per side."""
    pose = inverse_kinematics(joints)
    out = {}
    for side, s in ((0, "l_"), (1, "r_")):
        out[(side, "knee")] = 180.0 - _angle(joints[:, J[s + "hip"]], joints[:, J[s + "knee"]],
                                             joints[:, J[s + "ankle"]])
        out[(side, "elbow")] = 180.0 - _angle(joints[:, J[s + "shoulder"]], joints[:, J[s + "elbow"]],
                                              joints[:, J[s + "wrist"]])
        out[(side, "hip_flexion")] = np.degrees(pose.hip[:, side, 0])
        out[(side, "hip_abduction")] = np.degrees(pose.hip[:, side, 1])
        out[(side, "shoulder_flexion")] = np.degrees(pose.shoulder[:, side, 0])
        # abduction of the upper arm from the trunk's vertical, in the trunk's frontal plane
        out[(side, "shoulder_abduction")] = np.degrees(pose.shoulder[:, side, 1])
    return out


@pytest.fixture(scope="module", params=[(1000, 100.0, 3), (400, 40.0, 8)])
def trial(request):
    n, fps, seed = request.param
    p = BodyProportions.from_height(1.72)
    return p, synthesize_motion("rom", p, n, fps, rng=seed)


def test_every_joint_moves_through_its_range(trial):
    p, m = trial
    ang = _joint_angles(m.joints)
    for (side, name), a in ang.items():
        if name == "shoulder_abduction":   # IK splits a raised arm between flexion and abduction
            continue
        assert np.ptp(a) > MIN_RANGE_DEG[name], (side, name, np.ptp(a))
    # the shoulder abduction movement: the elbow rises to shoulder height and above, out to the side
    for side, s in ((0, "l_"), (1, "r_")):
        assert (m.joints[:, J[s + "elbow"], 2] > m.joints[:, J[s + "shoulder"], 2]).any()
    # the ankle: dorsi- and plantar-flexion on both sides, only while the foot is off the ground
    assert m.ankle.shape == (m.n_frames, 2)
    assert np.all(np.degrees(m.ankle.max(0)) > 12) and np.all(np.degrees(m.ankle.min(0)) < -20)
    moving = np.abs(m.ankle) > np.radians(1)
    assert not (moving & m.contacts).any()


def test_joints_move_in_turn(trial):
    """At most one leg lifted at a time, never an arm and a leg together, one arm at a time."""
    p, m = trial
    ang = _joint_angles(m.joints)
    legs = np.stack([np.maximum.reduce([np.abs(ang[(s, n)] - ang[(s, n)][0]) for n in ("knee", "hip_flexion")])
                     > MOVING_DEG for s in (0, 1)], 1)
    arms = np.stack([np.maximum.reduce([np.abs(ang[(s, n)] - ang[(s, n)][0]) for n in ("elbow", "shoulder_flexion")])
                     > MOVING_DEG for s in (0, 1)], 1)
    assert not (legs[:, 0] & legs[:, 1]).any()
    assert not (arms[:, 0] & arms[:, 1]).any()
    assert not (legs.any(1) & arms.any(1)).any()
    # every limb has its turn, legs before arms
    assert legs.any(0).all() and arms.any(0).all()
    assert np.flatnonzero(legs.any(1)).max() < np.flatnonzero(arms.any(1)).min()
    # one foot always on the ground, and it does not slide
    assert m.contacts.any(1).all()


def test_seeded_variation_and_time_scale():
    p = BodyProportions.from_height(1.8)
    a = synthesize_motion("rom", p, 300, 50.0, rng=1)
    b = synthesize_motion("rom", p, 300, 50.0, rng=1)
    c = synthesize_motion("rom", p, 300, 50.0, rng=2)
    np.testing.assert_array_equal(a.joints, b.joints)
    assert a.params["r_knee_flexion_deg"] != c.params["r_knee_flexion_deg"]
    assert np.abs(a.joints - c.joints).max() > 0.1
    # a short clip plays the trial faster, a long one at most 1.5x slower
    assert a.params["time_scale"] < 0.25
    long = synthesize_motion("rom", p, int(2 * NATURAL_DURATION_S * 10), 10.0, rng=1)
    assert long.params["time_scale"] == pytest.approx(1.5)
