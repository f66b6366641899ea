"""The synthetic depth camera: spec parsing, control points, sensor model, files written."""

from __future__ import annotations

import numpy as np
import pytest

from toolkit.anthropometry.proportions import BodyProportions
from toolkit.cameras import Camera
from toolkit.io.depth_readers import read_depth, read_depth_intrinsics
from toolkit.errors import InputError
from toolkit.io import read_png
from toolkit.motion import generate_motion
from toolkit.skeleton import JOINTS_13, JOINTS_17, SKELETON_14
from toolkit.body.model import BodyModel
from toolkit.synthetic.depth_sensor import (
    KINECT_AXIAL_NOISE,
    KINECT_BASELINE_M,
    KINECT_DISPARITY_STEP,
    RANDOM_DROPOUT_PROBABILITY,
    DepthCameraSpec,
    SecondPerson,
    apply_sensor_noise,
    control_points,
    render_depth_camera,
    render_depth_sequence,
)

#: Geometry checks against the mesh are exact up to float rounding.
GEOMETRY_TOLERANCE_M = 1e-6


# ------------------------------------------------------------------ spec
def test_spec_from_table_defaults_and_values():
    s = DepthCameraSpec.from_table({"resolution": [320, 240], "noise": False})
    assert s.resolution == (320, 240) and s.noise is False and s.second_person is None
    s = DepthCameraSpec.from_table({"second_person": True, "position": [1, 2, 1.5], "fov_deg": 60,
                                    "environment": "none"})
    assert s.second_person == SecondPerson() and s.position == (1.0, 2.0, 1.5) and s.fov_deg == 60.0
    s = DepthCameraSpec.from_table({"second_person": {"offset_m": [1.0, 0.0], "motion": "wave"}})
    assert s.second_person.offset_m == (1.0, 0.0) and s.second_person.motion == "wave"


@pytest.mark.parametrize("table, field", [
    ({"resolution": [320]}, "resolution"),
    ({"resolution": [320, -1]}, "resolution"),
    ({"noise": "yes"}, "noise"),
    ({"fov_deg": 500}, "fov_deg"),
    ({"position": [1, 2]}, "position"),
    ({"range_m": [3, 1]}, "range_m"),
    ({"environment": "beach"}, "environment"),
    ({"second_person": {"motion": "dance"}}, "second_person.motion"),
    ({"second_person": {"offset": [1, 2]}}, "second_person.offset"),
    ({"resolutoin": [320, 240]}, "resolutoin"),
])
def test_spec_errors_name_source_and_field(table, field):
    with pytest.raises(InputError) as e:
        DepthCameraSpec.from_table(table, "scene.toml")
    assert e.value.where.startswith("scene.toml: [depth_camera]") and field in e.value.where


# -------------------------------------------------------- control points
def _posed(seed=0):
    props = BodyProportions.sample(1.8, seed)
    model = BodyModel.sample(props, seed, detail=0.5)
    J = generate_motion("wave", props, 40, 30.0, rng=seed)[25]
    return props, model, J


def test_control_points_match_the_mesh():
    """Hand and foot tips (17 points) are the mesh's extreme vertices; the head centre sits below the head's top."""
    props, model, J = _posed()
    mesh = model.mesh(J)
    j13, j17 = control_points(J, props.height)
    s = props.height / 1.75
    ji = {n: i for i, n in enumerate(SKELETON_14.joint_names)}
    parts = {n: i + 1 for i, n in enumerate(SKELETON_14.part_names)}
    vpart = np.zeros(len(mesh.vertices), int)
    vpart[mesh.triangles.ravel()] = np.repeat(mesh.triangle_parts, 3)
    for side in ("l", "r"):
        wr, el = J[ji[f"{side}_wrist"]], J[ji[f"{side}_elbow"]]
        f = (wr - el) / np.linalg.norm(wr - el)
        V = mesh.vertices[vpart == parts[f"{side}_forearm"]]
        tip = V[np.argmax((V - wr) @ f)]
        np.testing.assert_allclose(tip, j17[JOINTS_17.index(f"{side}_hand")], atol=GEOMETRY_TOLERANCE_M)
        hand13 = j13[JOINTS_13.index(f"{side}_hand")]
        np.testing.assert_allclose(np.linalg.norm(hand13 - wr), 0.075 * s, atol=GEOMETRY_TOLERANCE_M)
        V = mesh.vertices[vpart == parts[f"{side}_shank"]]
        toe = j17[JOINTS_17.index(f"{side}_foot")]
        ankle = J[ji[f"{side}_ankle"]]
        w = (toe - j13[JOINTS_13.index(f"{side}_foot")]) / np.linalg.norm(toe - j13[JOINTS_13.index(f"{side}_foot")])
        np.testing.assert_allclose(V[np.argmax((V - ankle) @ w)], toe, atol=GEOMETRY_TOLERANCE_M)
    up = (J[ji["head"]] - J[ji["neck"]]) / np.linalg.norm(J[ji["head"]] - J[ji["neck"]])
    V = mesh.vertices[vpart == parts["head"]]
    top = np.max((V - j13[0]) @ up)
    np.testing.assert_allclose(top, 0.110 * s, atol=GEOMETRY_TOLERANCE_M)   # head ellipsoid half-height
    # joints shared with the 14-joint skeleton are copied
    for n in ("l_shoulder", "r_elbow", "l_hip", "r_knee"):
        np.testing.assert_array_equal(j13[JOINTS_13.index(n)], J[ji[n]])


# ------------------------------------------------------------ sensor model
def test_axial_noise_and_quantisation_statistics():
    cam = Camera.look_at("d", [0, 0, 0], [0, 1, 0], size=(200, 150), fov_x_deg=57)
    z = 3.0
    d = np.full((150, 200), z, np.float32)
    out = apply_sensor_noise(d, cam, np.random.default_rng(0))
    v = out[np.isfinite(out)].astype(np.float64)
    a, b, z0 = KINECT_AXIAL_NOISE
    sigma = a + b * (z - z0) ** 2
    step = KINECT_DISPARITY_STEP * z * z
    expected = np.sqrt(sigma ** 2 + step ** 2 / 12)
    assert abs(v.std() - expected) < 0.15 * expected
    assert abs(v.mean() - z) < 0.002
    # readings lie on the disparity lattice
    k = 1.0 / v / KINECT_DISPARITY_STEP
    np.testing.assert_allclose(k, np.round(k), atol=1e-3)
    dropped = 1 - np.isfinite(out).mean()
    assert dropped < 5 * RANDOM_DROPOUT_PROBABILITY + 0.01


def test_projector_shadow_left_of_a_foreground_edge():
    cam = Camera.look_at("d", [0, 0, 0], [0, 1, 0], size=(200, 100), fov_x_deg=57)
    d = np.full((100, 200), 4.0, np.float32)
    d[:, 100:140] = 1.5                                   # a bar in front of a wall
    out = apply_sensor_noise(d, cam, np.random.default_rng(1))
    f = cam.K[0, 0]
    width = f * KINECT_BASELINE_M * (1 / 1.5 - 1 / 4.0)   # shadow width in pixels
    row = np.isnan(out[40:60]).mean(0)
    assert row[100 - int(width) + 1:99].min() > 0.95       # the wall left of the bar is in shadow
    assert row[60:90].mean() < 0.02 and row[145:190].mean() < 0.02      # elsewhere only rare dropouts


def test_out_of_range_reads_nothing():
    cam = Camera.look_at("d", [0, 0, 0], [0, 1, 0], size=(40, 30), fov_x_deg=57)
    d = np.full((30, 40), 6.0, np.float32)
    assert np.isnan(apply_sensor_noise(d, cam, np.random.default_rng(0))).all()


# ------------------------------------------------------------------ files
def test_render_depth_camera_writes_the_layout(tmp_path):
    props = BodyProportions.sample(1.7, 5)
    model = BodyModel.sample(props, 5, detail=0.4)
    J = generate_motion("idle", props, 3, 30.0, rng=5)
    spec = DepthCameraSpec(resolution=(160, 120), environment="floor")
    out = render_depth_camera(tmp_path, spec, model, J, rng=5)
    info = read_depth_intrinsics(tmp_path / "depth_camera" / "intrinsics.toml")
    assert info.pose_known and info.camera.size == (160, 120)
    np.testing.assert_allclose(info.camera.cam_from_world, out.camera.cam_from_world)
    frames = sorted((tmp_path / "depth_camera" / "depth").glob("*.png"))
    assert [p.name for p in frames] == ["000000.png", "000001.png", "000002.png"]
    d = read_depth(frames[0])
    assert d.shape == (120, 160) and np.isfinite(d).any()
    mask = read_png(tmp_path / "groundtruth" / "depth_camera" / "masks" / "000000.png")
    assert mask.any() and set(np.unique(mask)) <= {0, 255}
    for name, n in (("skeleton13.npz", 13), ("skeleton17.npz", 17)):
        z = np.load(tmp_path / "groundtruth" / name, allow_pickle=False)
        assert z["joints"].shape == (3, n, 3) and len(z["names"]) == n and z["visible"].shape == (3, n)
    j13 = np.load(tmp_path / "groundtruth" / "skeleton13.npz")["joints"]
    np.testing.assert_allclose(j13, control_points(J, props.height)[0])
    assert np.isfinite(read_depth(tmp_path / "depth_camera" / "background.png")).any()


def test_second_person_is_rendered():
    props = BodyProportions.sample(1.75, 6)
    model = BodyModel.sample(props, 6, detail=0.4)
    J = generate_motion("idle", props, 2, 30.0, rng=6)
    spec = DepthCameraSpec(resolution=(160, 120), environment="none", second_person=SecondPerson((0.7, 0.0)))
    seq = render_depth_sequence(spec, model, J, rng=6)
    assert (seq.subject == 1).any() and (seq.subject == 2).any()
    assert seq.visible13.shape == (2, 13)
