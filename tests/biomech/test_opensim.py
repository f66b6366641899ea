"""The OpenSim engine on a synthetic person posed by known angles (skipped without opensim)."""

from __future__ import annotations

import numpy as np
import pytest

from toolkit.biomech.opensim_model import opensim_angles, opensim_available
from toolkit.biomech.synthetic import posed_points, random_rotation, smooth_motion
from toolkit.errors import InputError

#: IK (accuracy IK_ACCURACY) on exact data: the joints come back within this, metres.
RESIDUAL_M = 3e-3
#: Leg and elbow angles within this, degrees; shoulder rotation, weakly determined by a slightly bent
#: elbow, within SHOULDER_ROTATION_DEG.
ANGLE_DEG = 1.0
SHOULDER_ROTATION_DEG = 4.0

needs_opensim = pytest.mark.skipif(not opensim_available(), reason="opensim is not installed (pip install opensim)")


@needs_opensim
def test_inverse_kinematics_recovers_known_angles(tmp_path):
    rng = np.random.default_rng(11)
    truth = smooth_motion(30, rng)
    pts = posed_points(truth, 30, body=random_rotation(rng), origin=(0.5, -1.0, 0.95))
    res = opensim_angles(pts, 30.0, tmp_path)
    for name, v in truth.items():
        tol = SHOULDER_ROTATION_DEG if name.endswith("shoulder_rotation") else ANGLE_DEG
        assert np.abs(res.angles[name] - v).max() < tol, name
    worst = max(np.nanmax(r) for r in res.residuals_m.values())
    assert worst < RESIDUAL_M
    for f in ("model_generic", "model_scaled", "mot", "residuals"):
        assert res.files[f].exists(), f
    header = res.files["mot"].read_text().split("endheader")[0]
    assert "inDegrees=yes" in header
    # scaled to the person: thigh marker at the synthetic thigh length
    # (read from the .osim XML: OpenSim itself runs in a child process, never in this one)
    import xml.etree.ElementTree as ET

    marker = ET.parse(res.files["model_scaled"]).getroot().find(".//Marker[@name='l_knee']")
    knee = [float(x) for x in marker.find("location").text.split()]
    assert knee[1] == pytest.approx(-0.42, abs=1e-6)


def _legs_with_lateral_markers(n_frames: int, rng: np.random.Generator) -> tuple[dict, dict]:
    """Random leg and trunk angles (no shoulder or elbow) and their landmarks with lateral markers, posed
    by a random body rotation."""
    truth = {k: v for k, v in smooth_motion(n_frames, rng).items()
             if not k.startswith(("l_sh", "r_sh", "l_el", "r_el"))}
    return truth, posed_points(truth, n_frames, body=random_rotation(rng), lateral_markers=True)


@needs_opensim
def test_lateral_knee_markers_give_a_three_axis_knee_and_the_hip_rotation(tmp_path):
    rng = np.random.default_rng(13)
    truth, pts = _legs_with_lateral_markers(15, rng)
    res = opensim_angles(pts, 30.0, tmp_path)
    assert "l_knee_adduction" in res.angles.names and "r_knee_rotation" in res.angles.names
    for name in ("l_hip_rotation", "r_hip_rotation", "l_knee_flexion", "r_knee_flexion", "l_hip_adduction"):
        assert np.abs(res.angles[name] - truth[name]).max() < ANGLE_DEG, name
    np.testing.assert_allclose(res.angles["l_knee_adduction"], 0.0, atol=ANGLE_DEG)


@needs_opensim
def test_missing_joints_are_refused(tmp_path):
    pts = posed_points({}, 3)
    del pts["l_knee"]
    with pytest.raises(InputError, match="l_knee"):
        opensim_angles(pts, 30.0, tmp_path)


@pytest.mark.skipif(opensim_available(), reason="checks the message when opensim is absent")
def test_without_opensim_the_engine_says_how_to_install(tmp_path):
    with pytest.raises(InputError, match="pip install"):
        opensim_angles(posed_points({}, 3), 30.0, tmp_path)


@needs_opensim
def test_frames_without_markers_are_left_out_and_said(tmp_path):
    rng = np.random.default_rng(12)
    truth = {k: v for k, v in smooth_motion(8, rng).items() if k.endswith("flexion")}
    pts = {k: v.copy() for k, v in posed_points(truth, 8).items()}
    for v in pts.values():
        v[3] = np.nan
    pts["l_wrist"][5] = np.nan           # one marker missing: the frame is still solved
    res = opensim_angles(pts, 30.0, tmp_path)
    knee = res.angles["l_knee_flexion"]
    assert np.isnan(knee[3]) and np.isfinite(np.delete(knee, 3)).all()
    assert np.abs(np.delete(knee - truth["l_knee_flexion"], 3)).max() < ANGLE_DEG
    assert any(n.startswith("frame 3:") for n in res.notes)
    assert np.isnan(res.residuals_m["l_wrist"][5])


def test_orientation_targets_only_for_segments_that_markers_frame():
    # pure numpy: no OpenSim needed
    from toolkit.biomech.opensim_model import body_orientations

    rng = np.random.default_rng(14)
    truth = {k: v for k, v in smooth_motion(6, rng).items() if k.endswith("flexion")}
    assert body_orientations(posed_points(truth, 6)) == {}           # joint centres alone: no target
    pts = posed_points(truth, 6, lateral_markers=True)
    targets = body_orientations(pts)
    assert set(targets) == {"l_femur", "r_femur", "l_tibia", "r_tibia", "l_foot", "r_foot"}
    for R in targets.values():                                        # rotations in OpenSim's ground
        np.testing.assert_allclose(np.einsum("tji,tjk->tik", R, R), np.broadcast_to(np.eye(3), R.shape),
                                   atol=1e-9)
        np.testing.assert_allclose(np.linalg.det(R), 1.0, atol=1e-9)


@needs_opensim
def test_orientation_targets_are_met_on_exact_data_and_reported(tmp_path):
    import json

    rng = np.random.default_rng(15)
    truth, pts = _legs_with_lateral_markers(10, rng)
    res = opensim_angles(pts, 30.0, tmp_path)
    summary = json.loads(res.files["residuals"].read_text())
    assert set(summary["orientations_deg"]) == {"l_femur", "r_femur", "l_tibia", "r_tibia", "l_foot", "r_foot"}
    assert max(v["max"] for v in summary["orientations_deg"].values()) < ANGLE_DEG
