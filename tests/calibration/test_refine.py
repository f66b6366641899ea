"""Field models, line detection and camera refinement on the pitch's lines."""

from __future__ import annotations

import json

import cv2
import numpy as np
import pytest

from toolkit.calibration import (
    FieldModel,
    LineDetectorConfig,
    RefineConfig,
    apply_correction,
    calibration_error_px,
    detect_line_points,
    read_field_model,
    refine_camera,
    refine_rig,
    soccer_pitch,
    write_field_model,
)
from toolkit.cameras import Camera, Rig
from toolkit.errors import InputError
from toolkit.observe import RecordingObserver
from toolkit.synthetic.environment import PITCH_HALF_X, PITCH_HALF_Y, field_model, make_environment
from toolkit.synthetic.rigs import perturb_rig

SIZE = (640, 360)


def pitch_image(camera: Camera, rng=0) -> np.ndarray:
    """The synthetic broadcast ground seen by ``camera`` (texture warped by the plane homography)."""
    ground = make_environment("broadcast", rng)[0]
    tex = ground.texture
    h, w = tex.shape[:2]
    # texel (u, v) -> world (x, y, 0): texel centres, as painted
    A = np.array([[2 * PITCH_HALF_X / w, 0, -PITCH_HALF_X + PITCH_HALF_X / w],
                  [0, -2 * PITCH_HALF_Y / h, PITCH_HALF_Y - PITCH_HALF_Y / h],
                  [0, 0, 1]])
    P = camera.projection_matrix
    H = P[:, [0, 1, 3]] @ A
    img = cv2.warpPerspective(tex, H, camera.size, flags=cv2.INTER_LINEAR,
                              borderValue=(140, 170, 220))
    return img


def broadcast_camera(name="cam", eye=(-8.0, -42.0, 14.0), target=(-2.0, 2.0, 0.0), fov=28.0) -> Camera:
    return Camera.look_at(name, eye, target, size=SIZE, fov_x_deg=fov)


@pytest.fixture(scope="module")
def scene():
    cam = broadcast_camera()
    return cam, pitch_image(cam)


def test_soccer_pitch_matches_the_painted_layout():
    fm = soccer_pitch()
    assert len(fm.polylines) == 5
    pts, ids = fm.samples(0.05)
    assert np.allclose(pts[:, 2], 0)
    assert pts[:, 0].min() == pytest.approx(-55) and pts[:, 0].max() == pytest.approx(55)
    assert pts[:, 1].min() == pytest.approx(-35) and pts[:, 1].max() == pytest.approx(35)
    gaps = np.linalg.norm(np.diff(pts, axis=0), axis=1)[np.diff(ids) == 0]
    assert gaps.max() <= 0.05 + 1e-9
    circle = fm.polylines[2]
    assert np.allclose(np.linalg.norm(circle[:, :2], axis=1), 9.15)
    assert field_model("broadcast").name == fm.name and field_model("studio") is None


def test_field_model_round_trip_and_bad_files(tmp_path):
    fm = soccer_pitch(100, 64)
    path = write_field_model(tmp_path / "f.json", fm)
    back = read_field_model(path)
    assert back.name == fm.name and len(back.polylines) == len(fm.polylines)
    assert all(np.allclose(a, b) for a, b in zip(back.polylines, fm.polylines))
    with pytest.raises(InputError, match="no such file"):
        read_field_model(tmp_path / "missing.json")
    (tmp_path / "bad.json").write_text("{not json")
    with pytest.raises(InputError, match="bad.json"):
        read_field_model(tmp_path / "bad.json")
    (tmp_path / "short.json").write_text(json.dumps({"polylines": [[[0, 0, 0]]]}))
    with pytest.raises(InputError, match=r"polylines\[0\]"):
        read_field_model(tmp_path / "short.json")
    (tmp_path / "feet.json").write_text(json.dumps({"units": "ft", "polylines": [[[0, 0, 0], [1, 0, 0]]]}))
    with pytest.raises(InputError, match="units"):
        read_field_model(tmp_path / "feet.json")
    with pytest.raises(InputError, match="at least one"):
        FieldModel(())


def test_detected_centre_lines_lie_on_the_projected_model(scene):
    cam, img = scene
    lines = detect_line_points(img)
    assert len(lines) > 300
    model = cam.project(soccer_pitch().samples(0.01)[0])
    model = model[np.isfinite(model).all(1)]
    from scipy.spatial import cKDTree
    d, _ = cKDTree(model).query(lines.points)
    # nearly every detection is paint (the far lines alias in this unfiltered warp), and sits on the
    # model's centre line to a fraction of a pixel
    assert np.mean(d < 1.5) > 0.9
    assert np.median(d[d < 1.0]) < 0.35
    assert np.allclose(np.linalg.norm(lines.normals, axis=1), 1)


def test_detector_finds_nothing_on_plain_grass_and_rejects_bad_input():
    rng = np.random.default_rng(0)
    grass = np.clip(rng.normal([50, 120, 45], 12, (120, 160, 3)), 0, 255).astype(np.uint8)
    assert len(detect_line_points(grass)) == 0
    with pytest.raises(InputError, match="detect_line_points: image.*RGB uint8"):
        detect_line_points(grass.astype(float))
    with pytest.raises(InputError, match="max_width_px"):
        LineDetectorConfig(max_width_px=0)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_refinement_removes_most_of_an_8px_calibration_error(scene, seed):
    cam, img = scene
    joints = np.array([[-2.0 + dx, 2.0 + dy, z] for dx in (-0.3, 0.3) for dy in (-0.2, 0.2) for z in (0.1, 1.0, 1.7)])
    measured = perturb_rig(Rig((cam,)), 8.0, joints, rng=seed)[0]["cam"]
    assert calibration_error_px(measured, cam, joints) == pytest.approx(8.0, abs=0.5)
    obs = RecordingObserver()
    r = refine_camera(measured, img, soccer_pitch(), observer=obs)
    assert r.accepted, r.reason
    assert calibration_error_px(r.camera, cam, joints) < 1.0
    assert r.inliers_after > r.inliers_before
    assert np.allclose(r.camera.center, measured.center)
    # the recording gets the detected lines, the model before and after, the residual curve and a summary
    names = {d["name"] for _, d in obs.reports}
    assert {"calibration/lines", "calibration/model_before", "calibration/model_after",
            "calibration/cam/rms_px", "calibration/cam/summary"} <= names


def test_refinement_is_rejected_without_lines_and_keeps_the_camera():
    cam = broadcast_camera(eye=(0.0, -20.0, 30.0), target=(-30.0, 10.0, 0.0), fov=5.0)  # grass between lines
    img = pitch_image(cam)
    obs = RecordingObserver()
    r = refine_camera(cam, img, soccer_pitch(), observer=obs)
    assert not r.accepted and r.camera is cam
    assert "line points" in r.reason
    assert any(d.get("level") == "WARN" for d in obs.of_kind("text"))


def test_refine_rig_keeps_cameras_without_images_and_checks_names(scene):
    cam, img = scene
    other = broadcast_camera("other", eye=(30.0, -40.0, 14.0))
    measured = apply_correction(cam, np.array([0.002, -0.001, 0.0005]))
    rig, res = refine_rig(Rig((measured, other)), {"cam": img}, soccer_pitch())
    assert set(res) == {"cam"} and rig["other"] is other
    assert res["cam"].accepted
    with pytest.raises(InputError, match="images"):
        refine_rig(Rig((cam,)), {"nope": img}, soccer_pitch())
    with pytest.raises(InputError, match=r"image.*\(360, 640\)"):
        refine_camera(cam, img[:100], soccer_pitch())
    with pytest.raises(InputError, match="RGB uint8"):
        refine_camera(cam, img.astype(float), soccer_pitch())
    for bad in ((), (10.0, 20.0), (5.0, float("nan"))):
        with pytest.raises(InputError, match="gates_px"):
            RefineConfig(gates_px=bad)
    with pytest.raises(InputError, match="margin_px"):
        RefineConfig(margin_px=-1.0)


def test_apply_correction_is_a_rotation_about_the_centre_and_a_zoom(scene):
    cam, _ = scene
    c2 = apply_correction(cam, np.array([0.01, 0.02, -0.01]), np.log(1.1))
    assert np.allclose(c2.center, cam.center)
    assert c2.K[0, 0] == pytest.approx(cam.K[0, 0] * 1.1)
    assert np.allclose(c2.K[:2, 2], cam.K[:2, 2])
