"""The procedural motion library: invariants, realism measures, determinism, errors."""

from __future__ import annotations

import numpy as np
import pytest

from toolkit.anthropometry.proportions import BodyProportions
from toolkit.errors import InputError
from toolkit.motion.kinematics import bone_lengths14, sequence_bone_lengths
from toolkit.motion.library import (
    MOTIONS,
    RUN_CADENCE_HZ,
    WALK_CADENCE_HZ,
    generate_motion,
    synthesize_motion,
)
from toolkit.observe import RecordingObserver
from toolkit.skeleton import SKELETON_14

J = {n: i for i, n in enumerate(SKELETON_14.joint_names)}
ANKLES = [J["l_ankle"], J["r_ankle"]]
FPS = 25.0

#: Bone lengths are exact by construction (forward kinematics), metres.
LENGTH_TOL_M = 1e-9
#: Allowed ankle penetration below the standing ankle height, metres ("a few mm").
PENETRATION_TOL_M = 0.003
#: An ankle within this height above its standing height counts as on the ground, metres.
ON_GROUND_TOL_M = 0.005
#: Largest horizontal drift of an ankle over one ground contact ("a few cm"), metres.
FOOT_SLIDE_TOL_M = 0.03
#: Scene bound: |x| and |y| of every joint for 150 frames at 25 fps, metres.
SCENE_BOUND_M = 4.0
#: Cadence measured from ground-contact onsets may differ from the drawn one by rounding to frames, Hz.
CADENCE_TOL_HZ = 0.1


def contact_runs(on):
    """(start, stop) index pairs of runs of True."""
    d = np.diff(np.concatenate([[0], on.astype(int), [0]]))
    return list(zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1)))


def max_slide(joints, ankle_height):
    worst = 0.0
    for a in ANKLES:
        on = joints[:, a, 2] < ankle_height + ON_GROUND_TOL_M
        for s, e in contact_runs(on):
            xy = joints[s:e, a, :2]
            worst = max(worst, float(np.linalg.norm(xy - xy[0], axis=1).max()))
    return worst


def cadence(joints, ankle_height, fps):
    onsets = []
    for a in ANKLES:
        on = joints[:, a, 2] < ankle_height + ON_GROUND_TOL_M
        onsets += [s for s, _ in contact_runs(on) if s > 0]
    onsets = np.sort(onsets)
    return (len(onsets) - 1) / ((onsets[-1] - onsets[0]) / fps)


def pelvis(joints):
    return 0.5 * (joints[:, J["l_hip"]] + joints[:, J["r_hip"]])


def knee_forwardness(joints, motion):
    """Distance (m) of each knee in front of its hip-ankle line, along the pelvis forward axis (T, 2)."""
    fwd = np.stack([-np.sin(motion.pose.yaw), np.cos(motion.pose.yaw), np.zeros(len(joints))], 1)
    out = []
    for pre in ("l_", "r_"):
        h, k, a = joints[:, J[pre + "hip"]], joints[:, J[pre + "knee"]], joints[:, J[pre + "ankle"]]
        u = (a - h) / np.linalg.norm(a - h, axis=1, keepdims=True)
        foot = h + np.sum((k - h) * u, 1, keepdims=True) * u
        out.append(np.sum((k - foot) * fwd, 1))
    return np.stack(out, 1)


@pytest.fixture(scope="module")
def people():
    return [BodyProportions.sample(h, rng=i) for i, h in enumerate((1.55, 1.68, 1.75, 1.86))]


@pytest.fixture(scope="module")
def motions(people):
    """Every motion for 4 people and 2 seeds each: 150 frames at 25 fps."""
    return {(name, i): (p, synthesize_motion(name, p, 150, FPS, rng=100 + 7 * i))
            for name in MOTIONS for i, p in enumerate(people)}


def test_shapes_and_finiteness(motions):
    for (name, _), (p, m) in motions.items():
        assert m.joints.shape == (150, 14, 3), name
        assert np.all(np.isfinite(m.joints)), name
        assert m.contacts.shape == (150, 2) and m.contacts.dtype == bool


def test_bone_lengths_are_those_of_the_person(motions):
    for (name, _), (p, m) in motions.items():
        L = sequence_bone_lengths(m.joints)
        np.testing.assert_allclose(L, np.tile(bone_lengths14(p), (150, 1)), atol=LENGTH_TOL_M, err_msg=name)


def test_feet_never_below_the_ground(motions):
    for (name, _), (p, m) in motions.items():
        low = m.joints[:, ANKLES, 2].min()
        assert low >= p.ankle_height - PENETRATION_TOL_M, (name, low)
        assert m.joints[..., 2].min() > 0, name


def test_planted_feet_do_not_slide(motions):
    for (name, _), (p, m) in motions.items():
        # ground truth contacts: the ankle does not move at all
        for a, side in zip(ANKLES, (0, 1)):
            for s, e in contact_runs(m.contacts[:, side]):
                xyz = m.joints[s:e, a]
                assert np.abs(xyz - xyz[0]).max() < 1e-9, name
                assert np.allclose(xyz[:, 2], p.ankle_height, atol=1e-9), name
        # measured from the joints alone: drift while the ankle is on the ground
        assert max_slide(m.joints, p.ankle_height) < FOOT_SLIDE_TOL_M, name


def test_knees_never_hyperextend(motions):
    for (name, _), (p, m) in motions.items():
        assert np.all(m.pose.knee >= 0), name
        fwd = knee_forwardness(m.joints, m)
        bent = m.pose.knee > np.deg2rad(3)
        assert np.all(fwd[bent] > 0), name


def test_subject_stays_near_the_origin(motions):
    for (name, _), (p, m) in motions.items():
        assert np.abs(m.joints[..., :2]).max() < SCENE_BOUND_M, name
        assert np.linalg.norm(pelvis(m.joints)[0, :2]) < 3.5, name


def test_walk_cadence_speed_and_double_support(motions):
    for i in range(4):
        p, m = motions[("walk", i)]
        c = cadence(m.joints, p.ankle_height, FPS)
        assert WALK_CADENCE_HZ[0] - CADENCE_TOL_HZ <= c <= WALK_CADENCE_HZ[1] + CADENCE_TOL_HZ
        assert c == pytest.approx(m.params["cadence_hz"], abs=CADENCE_TOL_HZ)
        speed = np.linalg.norm(np.diff(pelvis(m.joints)[:, :2], axis=0), axis=1).sum() / (149 / FPS)
        assert 0.9 < speed < 1.9
        # walking never has both feet off the ground (the lower ankle stays within heel-rise height)
        assert (m.joints[:, ANKLES, 2].min(1) - p.ankle_height).max() < 0.06
        assert m.contacts.any(1).mean() > 0.5


def test_run_cadence_and_flight_phase(motions):
    for i in range(4):
        p, m = motions[("run", i)]
        c = cadence(m.joints, p.ankle_height, FPS)
        assert RUN_CADENCE_HZ[0] - CADENCE_TOL_HZ <= c <= RUN_CADENCE_HZ[1] + CADENCE_TOL_HZ
        flight = (m.joints[:, ANKLES, 2].min(1) > p.ankle_height + 0.02) & ~m.contacts.any(1)
        assert flight.mean() > 0.2
        speed = np.linalg.norm(np.diff(pelvis(m.joints)[:, :2], axis=0), axis=1).sum() / (149 / FPS)
        assert 2.0 < speed < 4.0


@pytest.mark.parametrize("name, min_corr", [("walk", -0.8), ("run", -0.25)])
def test_arms_swing_in_counter_phase(motions, name, min_corr):
    for i in range(4):
        p, m = motions[(name, i)]
        pel = pelvis(m.joints)
        fwd = np.stack([-np.sin(m.pose.yaw), np.cos(m.pose.yaw)], 1)
        for pre in ("l_", "r_"):
            wrist = np.sum((m.joints[:, J[pre + "wrist"], :2] - pel[:, :2]) * fwd, 1)
            ankle = np.sum((m.joints[:, J[pre + "ankle"], :2] - pel[:, :2]) * fwd, 1)
            assert np.corrcoef(wrist, ankle)[0, 1] < min_corr


def test_walk_knee_flexes_in_swing(motions):
    for i in range(4):
        p, m = motions[("walk", i)]
        knee = np.rad2deg(m.pose.knee)
        assert 50 < knee.max() < 75           # swing peak of normal gait is about 60 deg
        assert knee.min() < 8                 # nearly straight at heel strike


def test_jump_crouches_takes_off_and_lands(motions):
    for i in range(4):
        p, m = motions[("jump", i)]
        z = pelvis(m.joints)[:, 2]
        stand = z[0]
        airborne = (m.joints[:, ANKLES, 2].min(1) > p.ankle_height + 0.03)
        assert airborne.any()
        first = int(np.flatnonzero(airborne)[0])
        assert z[:first].min() < stand - 0.12                     # crouch before takeoff
        assert z.max() > stand + 0.08                             # flight above standing height
        after = np.flatnonzero(~airborne[first:])[0] + first       # landing
        assert z[after:after + 15].min() < stand - 0.05          # landing absorbed by the knees
        assert not m.contacts[airborne].any()


def test_kick_has_a_standing_leg(motions):
    for i in range(4):
        p, m = motions[("kick", i)]
        kick = 0 if m.params["kick_leg"] == "left" else 1
        assert m.contacts[:, 1 - kick].all()
        ankle = m.joints[:, ANKLES[kick]]
        assert ankle[:, 2].max() > p.ankle_height + 0.3
        pel = pelvis(m.joints)
        fwd = np.stack([-np.sin(m.pose.yaw), np.cos(m.pose.yaw)], 1)
        assert np.sum((ankle[:, :2] - pel[:, :2]) * fwd, 1).max() > 0.4   # kicks forward


def test_turn_rotates_about_180_degrees_in_place(motions):
    for i in range(4):
        p, m = motions[("turn", i)]
        hips = m.joints[:, J["r_hip"], :2] - m.joints[:, J["l_hip"], :2]
        ang = np.unwrap(np.arctan2(hips[:, 1], hips[:, 0]))
        first_turn = abs(ang[min(len(ang) - 1, int((m.params["lead_in_s"] + m.params["turn_s"]) * FPS) + 2)]
                         - ang[0])
        assert 140 < np.rad2deg(first_turn) < 220
        drift = np.linalg.norm(pelvis(m.joints)[:, :2] - pelvis(m.joints)[0, :2], axis=1).max()
        assert drift < 0.15


def test_wave_raises_one_arm(motions):
    for i in range(4):
        p, m = motions[("wave", i)]
        a = "l_" if m.params["wave_arm"] == "left" else "r_"
        o = "r_" if a == "l_" else "l_"
        head = m.joints[:, J["head"], 2]
        assert (m.joints[:, J[a + "wrist"], 2] > head).mean() > 0.2
        assert (m.joints[:, J[o + "wrist"], 2] < m.joints[:, J["neck"], 2] - 0.2).all()
        assert m.contacts.all()


def test_crouch_goes_down_and_up(motions):
    for i in range(4):
        p, m = motions[("crouch", i)]
        z = pelvis(m.joints)[:, 2]
        assert z.min() < z[0] - 0.25 * (p.thigh + p.shank)
        bottom = int(np.argmin(z))
        assert z[bottom:].max() > z[0] - 0.02 or z[:bottom].max() > z[0] - 0.02
        assert m.contacts.all()
        assert np.rad2deg(m.pose.knee).max() > 70


def test_idle_stands_still(motions):
    for i in range(4):
        p, m = motions[("idle", i)]
        assert m.contacts.all()
        pel = pelvis(m.joints)
        assert np.linalg.norm(pel[:, :2] - pel[0, :2], axis=1).max() < 0.08


def test_each_motion_is_distinct(motions):
    """Motion signatures: pelvis speed, pelvis height range, wrist above head, yaw change, foot height."""
    sig = {}
    for name in MOTIONS:
        p, m = motions[(name, 2)]
        pel = pelvis(m.joints)
        sig[name] = np.array([
            np.linalg.norm(np.diff(pel[:, :2], axis=0), axis=1).sum() / 6.0,
            np.ptp(pel[:, 2]),
            (m.joints[:, [J["l_wrist"], J["r_wrist"]], 2].max(1) > m.joints[:, J["head"], 2]).mean(),
            abs(np.unwrap(m.pose.yaw)[-1] - m.pose.yaw[0]) / np.pi,
            m.joints[:, ANKLES, 2].max() - p.ankle_height,
        ])
    names = list(MOTIONS)
    for a in range(len(names)):
        for b in range(a + 1, len(names)):
            assert np.abs(sig[names[a]] - sig[names[b]]).max() > 0.04, (names[a], names[b])


@pytest.mark.parametrize("name", MOTIONS)
def test_same_seed_same_motion_different_seed_different_motion(name):
    p = BodyProportions.from_height(1.7)
    a = generate_motion(name, p, 60, 30.0, rng=5)
    b = generate_motion(name, p, 60, 30.0, rng=np.random.default_rng(5))
    c = generate_motion(name, p, 60, 30.0, rng=6)
    np.testing.assert_array_equal(a, b)
    assert np.abs(a - c).max() > 0.05


def test_variation_across_seeds():
    p = BodyProportions.from_height(1.7)
    ms = [synthesize_motion("walk", p, 10, FPS, rng=s) for s in range(20)]
    for key in ("cadence_hz", "step_length_ratio", "heading", "arm_swing_deg"):
        values = [m.params[key] for m in ms]
        assert np.std(values) > 0, key
    arms = {synthesize_motion("wave", p, 10, FPS, rng=s).params["wave_arm"] for s in range(20)}
    legs = {synthesize_motion("kick", p, 10, FPS, rng=s).params["kick_leg"] for s in range(20)}
    assert arms == {"left", "right"} and legs == {"left", "right"}


@pytest.mark.parametrize("fps", [10.0, 60.0])
def test_other_frame_rates(fps):
    p = BodyProportions.from_height(1.8)
    m = synthesize_motion("walk", p, int(3 * fps), fps, rng=1)
    c = cadence(m.joints, p.ankle_height, fps)
    assert c == pytest.approx(m.params["cadence_hz"], abs=0.25 if fps < 20 else CADENCE_TOL_HZ)


def test_single_frame_and_long_sequences():
    p = BodyProportions.from_height(1.7)
    for name in MOTIONS:
        assert generate_motion(name, p, 1, FPS, rng=0).shape == (1, 14, 3)
    long = generate_motion("run", p, 750, FPS, rng=0)          # 30 s on a circle
    assert np.abs(long[..., :2]).max() < SCENE_BOUND_M


def test_observer_receives_one_report_per_frame():
    obs = RecordingObserver()
    j = generate_motion("wave", BodyProportions.from_height(1.7), 12, FPS, rng=0, observer=obs)
    reps = obs.of_kind("joints3d")
    assert len(reps) == 12 and [r["frame"] for r in reps] == list(range(12))
    np.testing.assert_array_equal(reps[5]["joints"], j[5])


@pytest.mark.parametrize("kwargs, where", [
    (dict(name="moonwalk"), "motion"),
    (dict(n_frames=0), "n_frames"),
    (dict(n_frames=-3), "n_frames"),
    (dict(n_frames=2.5), "n_frames"),
    (dict(fps=0.0), "fps"),
    (dict(fps=-25.0), "fps"),
    (dict(fps=float("nan")), "fps"),
])
def test_bad_arguments_raise(kwargs, where):
    args = dict(name="walk", proportions=BodyProportions.from_height(1.7), n_frames=10, fps=FPS, rng=0)
    args.update(kwargs)
    with pytest.raises(InputError) as e:
        generate_motion(**args)
    assert e.value.where == where
    if where == "motion":
        assert e.value.found == repr("moonwalk") and "walk" in e.value.expected
