"""The project's own joint angles on synthetic skeletons posed by known angles."""

from __future__ import annotations

import numpy as np
import pytest

from toolkit.biomech.synthetic import posed_points, random_rotation
from toolkit.biomech import joint_angles, segment_frames
from toolkit.biomech.angles import cardan_zxy, rotation_zxy
from toolkit.biomech.segments import foot_pitch_offsets
from toolkit.errors import InputError

#: Exact recovery: the only error is floating point (arcsin near its ends loses a few digits).
EXACT_DEG = 1e-6
N_FRAMES = 40


def _sagittal(rng, T):
    """Flexion-only angles for both sides, realistic ranges (degrees)."""
    v = {}
    for s in "lr":
        v[f"{s}_hip_flexion"] = rng.uniform(-20, 100, T)
        v[f"{s}_knee_flexion"] = rng.uniform(5, 120, T)
        v[f"{s}_ankle_dorsiflexion"] = rng.uniform(-40, 25, T)
        v[f"{s}_shoulder_flexion"] = rng.uniform(-40, 80, T)
        v[f"{s}_elbow_flexion"] = rng.uniform(5, 140, T)
    return v


def test_cardan_round_trip():
    rng = np.random.default_rng(0)
    ang = np.column_stack([rng.uniform(-170, 170, 50), rng.uniform(-85, 85, 50), rng.uniform(-170, 170, 50)])
    np.testing.assert_allclose(cardan_zxy(rotation_zxy(ang)), ang, atol=1e-9)


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_sagittal_angles_exact_from_joint_centres_only(seed):
    """Flexion of every joint from the 14 joints (+ toe) alone, any body heading and tilt."""
    rng = np.random.default_rng(seed)
    truth = _sagittal(rng, N_FRAMES)
    pts = posed_points(truth, N_FRAMES, body=random_rotation(rng), origin=rng.normal(0, 1, 3))
    got = joint_angles(pts, fps=50.0)
    for name, v in truth.items():
        np.testing.assert_allclose(got[name], v, atol=EXACT_DEG, err_msg=name)
    # a purely sagittal pose has no ab/adduction or rotation
    for name in got.names:
        if name.endswith(("adduction", "abduction", "rotation")):
            np.testing.assert_allclose(got[name], 0.0, atol=EXACT_DEG, err_msg=name)
    np.testing.assert_allclose(got.time, np.arange(N_FRAMES) / 50.0)


@pytest.mark.parametrize("seed", [4, 5])
def test_three_dimensional_hip_angles_exact_with_lateral_knee_markers(seed):
    rng = np.random.default_rng(seed)
    truth = _sagittal(rng, N_FRAMES)
    for s in "lr":
        truth[f"{s}_hip_adduction"] = rng.uniform(-25, 25, N_FRAMES)
        truth[f"{s}_hip_rotation"] = rng.uniform(-40, 40, N_FRAMES)
    pts = posed_points(truth, N_FRAMES, body=random_rotation(rng), lateral_markers=True)
    got = joint_angles(pts, fps=100.0)
    for name, v in truth.items():
        np.testing.assert_allclose(got[name], v, atol=EXACT_DEG, err_msg=name)


def test_adduction_and_abduction_exact_without_markers_and_signed_like_plugin_gait():
    """Ab/adduction alone (a bent knee and elbow) comes from the joint centres; signs mirror per side."""
    rng = np.random.default_rng(6)
    T = N_FRAMES
    truth = {f"{s}_{k}": v for s in "lr" for k, v in (("knee_flexion", rng.uniform(20, 90, T)),
                                                      ("elbow_flexion", rng.uniform(20, 120, T)),
                                                      ("hip_adduction", rng.uniform(-20, 20, T)),
                                                      ("shoulder_abduction", rng.uniform(-10, 80, T)))}
    pts = posed_points(truth, T, body=random_rotation(rng))
    got = joint_angles(pts, fps=30.0)
    for name, v in truth.items():
        np.testing.assert_allclose(got[name], v, atol=EXACT_DEG, err_msg=name)
    # adduction moves the knee towards the midline, on both sides
    one = posed_points({"l_hip_adduction": 10.0, "r_hip_adduction": 10.0, "l_knee_flexion": 30.0,
                        "r_knee_flexion": 30.0}, 1)
    gap_knees = np.linalg.norm(one["l_knee"] - one["r_knee"])
    gap_hips = np.linalg.norm(one["l_hip"] - one["r_hip"])
    assert gap_knees < gap_hips


def test_signs_on_a_plain_pose():
    """Knee flexion puts the ankle behind the knee; dorsiflexion lifts the toe; flexion brings the knee forward."""
    pts = posed_points({"r_hip_flexion": 30.0, "r_knee_flexion": 60.0, "r_ankle_dorsiflexion": 10.0}, 1)
    # body default: anterior = world +x, up = +z
    assert pts["r_knee"][0, 0] > pts["r_hip"][0, 0]
    assert pts["r_ankle"][0, 0] < pts["r_knee"][0, 0]
    got = joint_angles(pts, 1.0)
    assert got["r_knee_flexion"][0] == pytest.approx(60.0)
    assert got["r_ankle_dorsiflexion"][0] == pytest.approx(10.0)
    assert got["r_hip_flexion"][0] == pytest.approx(30.0)


def test_straight_limb_without_markers_reads_no_rotation_and_stays_finite():
    pts = posed_points({"l_hip_flexion": 20.0}, 3)
    got = joint_angles(pts, 1.0)
    assert np.all(np.isfinite(got.degrees))
    np.testing.assert_allclose(got["l_hip_flexion"], 20.0, atol=EXACT_DEG)
    np.testing.assert_allclose(got["l_hip_rotation"], 0.0, atol=EXACT_DEG)


def test_heel_and_static_trial_offsets_level_the_foot():
    """With a heel below the ankle-toe line, the foot's axis is heel-to-toe (a level foot reads 0)."""
    truth = {"r_ankle_dorsiflexion": np.linspace(-20, 15, 10), "l_ankle_dorsiflexion": np.linspace(5, -5, 10)}
    pts = posed_points(truth, 10)
    frames = segment_frames(pts)
    for s in "lr":
        fx, fy = frames[f"{s}_foot"][..., 0], frames[f"{s}_foot"][..., 1]
        pts[f"{s}_heel"] = pts[f"{s}_ankle"] - 0.05 * fx - 0.08 * fy
        pts[f"{s}_toe"] = pts[f"{s}_toe"] - 0.08 * fy
    # the toe moved down with the heel: heel-to-toe is parallel to the true foot axis again
    got = joint_angles(pts, 1.0)
    for name, v in truth.items():
        np.testing.assert_allclose(got[name], v, atol=EXACT_DEG, err_msg=name)
    static = posed_points({}, 5)
    static_frames = segment_frames(static)
    for s in "lr":
        fx, fy = static_frames[f"{s}_foot"][..., 0], static_frames[f"{s}_foot"][..., 1]
        static[f"{s}_heel"] = static[f"{s}_ankle"] - 0.05 * fx - 0.08 * fy
        static[f"{s}_toe"] = static[f"{s}_toe"] - 0.08 * fy
    offsets = foot_pitch_offsets(static)
    assert set(offsets) == {"l", "r"}
    moving = {k: v for k, v in pts.items() if not k.endswith("heel")}
    got_static = joint_angles(moving, 1.0, static=static)
    for name, v in truth.items():
        np.testing.assert_allclose(got_static[name], v, atol=EXACT_DEG, err_msg=name)
    # without any offset the lowered toe reads as plantarflexion
    plain = joint_angles(moving, 1.0)
    assert np.all(plain["r_ankle_dorsiflexion"] < truth["r_ankle_dorsiflexion"] - 5)


def test_missing_joints_give_nan_and_missing_segments_no_column():
    pts = posed_points({"l_knee_flexion": 40.0}, 4)
    pts["l_knee"] = pts["l_knee"].copy()
    pts["l_knee"][2] = np.nan
    del pts["r_toe"]
    got = joint_angles(pts, 1.0)
    assert np.isnan(got["l_knee_flexion"][2]) and np.isfinite(got["l_knee_flexion"][[0, 1, 3]]).all()
    assert "r_ankle_dorsiflexion" not in got.names and "l_ankle_dorsiflexion" in got.names


def test_bad_input_names_the_argument():
    pts = posed_points({}, 2)
    with pytest.raises(InputError, match="fps"):
        joint_angles(pts, 0.0)
    with pytest.raises(InputError, match="l_hip"):
        joint_angles({k: v for k, v in pts.items() if k != "l_hip"}, 1.0)
    bad = dict(pts, l_knee=np.zeros((3, 3)))
    with pytest.raises(InputError, match="l_knee"):
        joint_angles(bad, 1.0)


def test_pelvis_and_thorax_markers_set_the_tilt():
    """ASIS/PSIS and C7/T10/CLAV/STRN tilted forward by 12 degrees: hip and shoulder flexion read 12 more."""
    rng = np.random.default_rng(7)
    truth = _sagittal(rng, 10)
    body = random_rotation(rng)
    pts = posed_points(truth, 10, body=body)
    tilt = np.deg2rad(12.0)
    # the pelvis and thorax turned about their right axis (Z), anterior towards inferior: X -> X cos - Y sin
    X = body[:, 0] * np.cos(tilt) - body[:, 1] * np.sin(tilt)
    Y = body[:, 0] * np.sin(tilt) + body[:, 1] * np.cos(tilt)
    Z = body[:, 2]
    mid = 0.5 * (pts["l_hip"] + pts["r_hip"])
    for s, sign in (("l", -1), ("r", 1)):
        pts[f"{s}_asis"] = mid + 0.06 * X + 0.05 * Y + sign * 0.12 * Z
        pts[f"{s}_psis"] = mid - 0.10 * X + 0.05 * Y + sign * 0.04 * Z
    top = pts["neck"]
    pts["c7"], pts["clav"] = top - 0.06 * X, top + 0.06 * X
    pts["t10"], pts["strn"] = top - 0.25 * Y - 0.08 * X, top - 0.25 * Y + 0.08 * X
    got = joint_angles(pts, 1.0)
    for s in "lr":
        np.testing.assert_allclose(got[f"{s}_hip_flexion"], truth[f"{s}_hip_flexion"] + 12.0, atol=EXACT_DEG)
        np.testing.assert_allclose(got[f"{s}_shoulder_flexion"], truth[f"{s}_shoulder_flexion"] + 12.0,
                                   atol=EXACT_DEG)
        np.testing.assert_allclose(got[f"{s}_knee_flexion"], truth[f"{s}_knee_flexion"], atol=EXACT_DEG)
