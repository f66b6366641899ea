"""Template fit (source 000 §2.2, claim 8): database pose, exact fit, posed and projected template."""

from __future__ import annotations

import numpy as np
import pytest

from toolkit.anthropometry.proportions import BodyProportions
from toolkit.cameras import Camera
from toolkit.errors import InputError
from toolkit.motion import generate_motion
from toolkit.observe import RecordingObserver
from toolkit.synthetic.render import Raycaster
from toolkit.template import (
    PoseDatabase,
    Template,
    approximate_pose,
    camera_with_offset,
    canonical_poses,
    exact_fit,
    fit_template_pose,
    thin_thick,
)

#: The exact fit is closed-form; only float rounding (and the iterative undistortion) remain.
EXACT_FIT_TOL_PX = 0.01
#: A pose that is in the database, seen from a yaw on the search grid, is found to this RMS error:
#: the search uses weak perspective, off by about body depth / distance (0.5 m / 10 m) of the
#: pose's image extent from the pelvis (measured 0.9 px here); a wrong pose or yaw gives > 10 px.
DATABASE_HIT_TOL_PX = 2.0


def _camera(dist=None, size=(1280, 720)):
    cam = Camera.look_at("c", eye=(6.0, -8.0, 3.0), target=(0.0, 0.0, 1.0), size=size, fov_x_deg=40.0)
    if dist is not None:
        cam = cam.replace(dist=np.asarray(dist, float))
    return cam


@pytest.fixture(scope="module")
def walk():
    return generate_motion("walk", BodyProportions.from_height(1.75), 30, 25.0, rng=5)


@pytest.mark.parametrize("dist", [None, [-0.12, 0.03, 0.001, -0.0005, 0.0]])
def test_exact_fit_reprojects_onto_2d_joints(walk, dist):
    rng = np.random.default_rng(1)
    cam = _camera(dist)
    approx = walk[3] + rng.normal(0, 0.05, (14, 3))
    target = cam.project(walk[10]) + rng.normal(0, 3.0, (14, 2))
    fitted = exact_fit(approx, target, cam)
    err = np.linalg.norm(cam.project(fitted) - target, axis=1)
    assert err.max() < EXACT_FIT_TOL_PX
    # the camera-frame depth of every joint is kept (plane parallel to the image plane)
    np.testing.assert_allclose(cam.depth_of(fitted), cam.depth_of(approx), atol=1e-9)
    # bone lengths may change
    assert not np.allclose(np.linalg.norm(fitted[1] - fitted[0]), np.linalg.norm(approx[1] - approx[0]))


def test_exact_fit_keeps_joints_without_2d(walk):
    cam = _camera()
    target = cam.project(walk[0]) + 2.0
    target[4] = np.nan
    fitted = exact_fit(walk[0], target, cam)
    np.testing.assert_array_equal(fitted[4], walk[0][4])
    ok = np.isfinite(target).all(1)
    assert np.abs(cam.project(fitted[ok]) - target[ok]).max() < EXACT_FIT_TOL_PX


def test_exact_fit_bad_input(walk):
    cam = _camera()
    with pytest.raises(InputError, match="joints2d"):
        exact_fit(walk[0], np.zeros((13, 2)), cam)
    with pytest.raises(InputError, match="approx_joints3d"):
        exact_fit(walk[0][:, :2], np.zeros((14, 2)), cam)
    behind = walk[0].copy()
    behind[2] = 2 * cam.center - behind[2]  # mirrored through the camera centre: behind it
    with pytest.raises(InputError, match="behind"):
        exact_fit(behind, cam.project(walk[0]), cam)


def test_camera_with_offset_shifts_projections_exactly(walk):
    cam = _camera([-0.1, 0.02, 0.0, 0.0, 0.0])
    shifted = camera_with_offset(cam, (3.5, -7.25))
    np.testing.assert_allclose(shifted.project(walk[0]) - cam.project(walk[0]), np.tile([3.5, -7.25], (14, 1)),
                               atol=1e-9)
    with pytest.raises(InputError, match="offset"):
        camera_with_offset(cam, (1.0, np.nan))


def test_canonical_poses_remove_position_and_heading(walk):
    c = canonical_poses(walk)
    pelvis = 0.5 * (c[:, 8] + c[:, 11])
    np.testing.assert_allclose(pelvis, 0.0, atol=1e-12)
    lat = c[:, 8] - c[:, 11]
    np.testing.assert_allclose(lat[:, 1], 0.0, atol=1e-12)
    assert (lat[:, 0] > 0).all()


def test_approximate_pose_finds_a_database_pose(walk):
    db = PoseDatabase.from_joints(walk, 1.75)
    cam = _camera()
    # database pose 7 turned by a yaw on the grid (40 deg) and placed somewhere in view
    yaw = np.radians(40.0)
    R = np.array([[np.cos(yaw), -np.sin(yaw), 0], [np.sin(yaw), np.cos(yaw), 0], [0, 0, 1]])
    pose = db.poses[7] @ R.T + [0.3, -0.2, walk[7][[8, 11], 2].mean()]
    x = cam.project(pose)
    obs = RecordingObserver()
    ap = approximate_pose(x, cam, db, observer=obs)
    assert ap and ap.index == 7
    assert ap.error_px < DATABASE_HIT_TOL_PX
    assert np.isclose(ap.yaw, yaw, atol=1e-9)
    assert np.isclose(ap.depth, cam.depth_of(0.5 * (pose[8] + pose[11])), rtol=0.02)
    assert obs.of_kind("text") and obs.of_kind("joints3d")


def test_approximate_pose_needs_three_joints(walk):
    db = PoseDatabase.from_joints(walk, 1.75)
    x = np.full((14, 2), np.nan)
    x[:2] = 100.0
    ap = approximate_pose(x, _camera(), db)
    assert not ap and np.isnan(ap.joints3d).all()


def test_fit_template_pose_from_2d_only_is_exact(walk):
    db = PoseDatabase.from_joints(walk[::3], 1.75)
    cam = _camera()
    x = cam.project(walk[4]) + np.random.default_rng(2).normal(0, 2.0, (14, 2))
    tp = fit_template_pose(cam, joints2d=x, database=db)
    assert tp.source == "database"
    assert tp.reprojection_px < EXACT_FIT_TOL_PX
    # with complete 3D joints those are the approximate pose
    tp3 = fit_template_pose(cam, joints2d=x, joints3d=walk[4])
    assert tp3.source == "joints3d" and tp3.reprojection_px < EXACT_FIT_TOL_PX


def test_fit_template_pose_without_joints_fills_the_silhouette_box(walk):
    cam = _camera()
    x = cam.project(walk[0])
    sil = np.zeros((720, 1280), bool)
    top, bottom = int(x[:, 1].min()) - 10, int(x[:, 1].max()) + 10
    left, right = int(x[:, 0].min()) - 5, int(x[:, 0].max()) + 5
    sil[top:bottom, left:right] = True
    tp = fit_template_pose(cam, silhouette=sil)
    assert tp.source == "silhouette"
    uv = cam.project(tp.joints3d)
    assert left - 20 < uv[:, 0].min() and uv[:, 0].max() < right + 20
    assert np.isclose(uv[:, 1].max() - uv[:, 1].min(), bottom - top, rtol=0.05)
    with pytest.raises(InputError, match="silhouette"):
        fit_template_pose(cam, silhouette=np.zeros((720, 1280), bool))


def test_template_render_matches_the_scene_raycaster(walk):
    cam = _camera(size=(320, 180))
    t = Template(1.75)
    labels, depth = t.render(walk[0], cam)
    ref_l, _, ref_d = Raycaster().cast(cam, [t.mesh(walk[0])])
    np.testing.assert_array_equal(labels, ref_l)
    np.testing.assert_allclose(depth, ref_d, atol=1e-4, equal_nan=True)
    assert set(np.unique(labels)) == set(range(11))


def test_thin_thick_contain_and_order():
    labels = np.zeros((60, 80), np.uint8)
    depth = np.full((60, 80), np.nan, np.float32)
    labels[10:50, 10:40] = 2
    depth[10:50, 10:40] = 5.0
    labels[20:30, 30:70] = 3  # in front of part 2
    depth[20:30, 30:70] = 4.0
    thin, thick = thin_thick(labels, depth, 3)
    assert np.all((thin == 0) | (thin == labels))  # thin keeps labels, drops pixels
    assert np.all(thick[labels > 0] > 0)  # thick covers the projection
    assert thin[30, 20] == 2 and thin[25, 60] == 3
    assert thin[20, 20] == 2 and thin[19, 35] == 0  # next to part 3: dropped
    # where both parts' dilations meet, the front part wins
    assert thick[18, 35] == 3 and thick[32, 35] == 3
    assert thick[8, 20] == 2 and thick[52, 20] == 2
    same = (thin > 0) & (thin == thick)
    assert same.sum() > 0.5 * (labels > 0).sum()
    t0, k0 = thin_thick(labels, depth, 0)
    np.testing.assert_array_equal(t0, labels)
    np.testing.assert_array_equal(k0, labels)


def test_template_project_radius_scales_with_image_height(walk):
    cam = _camera(size=(640, 360))
    t = Template(1.75)
    p = t.project(walk[0], cam, fraction=0.02)
    assert p.radius_px == max(1, round(0.02 * p.height_px))
    assert p.height_px > 100
    big = t.project(walk[0], cam.scaled(2.0), fraction=0.02)
    assert abs(big.height_px - 2 * p.height_px) < 2.0
    assert np.isfinite(p.part_depth).all()
    with pytest.raises(InputError, match="joints3d"):
        t.project(np.full((14, 3), np.nan), cam)


def test_database_from_bvh_matches_the_motion(tmp_path, walk):
    from toolkit.motion import write_bvh
    from toolkit.skeleton.mappings import SKELETON14_BVH_TO_14

    path = tmp_path / "walk.bvh"
    write_bvh(path, walk, fps=25.0)
    db = PoseDatabase.from_bvh([path], 1.75, every=5, mapping=SKELETON14_BVH_TO_14, units=0.01)
    assert len(db) == 6 and db.sources[1] == "walk.bvh:5"
    # same body, same poses: only position and heading were removed (bone lengths retargeted to the
    # same median body, so within the BVH round trip's precision)
    np.testing.assert_allclose(db.poses, canonical_poses(walk[::5]), atol=0.01)
    with pytest.raises(InputError, match="paths"):
        PoseDatabase.from_bvh([])
