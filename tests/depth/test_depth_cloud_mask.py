"""Depth to points, the view frame, normals from 3 x 3 gradients, PCA and the user mask."""

from __future__ import annotations

import numpy as np
import pytest

from toolkit.cameras import Camera
from toolkit.pointcloud.cloud import (
    ViewFrame,
    depth_to_points,
    open3d_points_from_depth,
    principal_direction,
    user_cloud,
)
from toolkit.pointcloud.mask import BackgroundModel, MaskConfig, user_mask
from toolkit.pointcloud.normals import grid_normals, normal_map
from toolkit.errors import InputError

#: Back-projection agrees with Open3D to float32 rounding.
BACKPROJECT_TOLERANCE_M = 1e-5
#: Normals of exact planes and spheres from the 3 x 3 kernel, degrees.
NORMAL_TOLERANCE_DEG = 0.5
#: The sphere's normals use a central difference over 2 pixels of a curved surface.
SPHERE_NORMAL_TOLERANCE_DEG = 2.0
#: The background-subtraction mask of a noisy frame against the exact person mask.
MIN_MASK_IOU = 0.85


def _camera(size=(160, 120), pose=np.eye(4)):
    w, h = size
    f = 150.0
    return Camera("d", [[f, 0, (w - 1) / 2], [0, f, (h - 1) / 2], [0, 0, 1]], np.zeros(5), size, pose)


def _angle_deg(a, b):
    c = np.sum(a * b, -1) / (np.linalg.norm(a, axis=-1) * np.linalg.norm(b, axis=-1))
    return np.degrees(np.arccos(np.clip(c, -1, 1)))


def test_backprojection_matches_open3d():
    cam = _camera()
    rng = np.random.default_rng(0)
    d = rng.uniform(1, 3, (120, 160)).astype(np.float32)
    d[rng.random(d.shape) < 0.1] = np.nan
    P, rows, cols = depth_to_points(d, cam)
    Q = open3d_points_from_depth(d, cam)
    assert len(P) == len(Q) == np.isfinite(d).sum()
    np.testing.assert_allclose(P, Q, atol=BACKPROJECT_TOLERANCE_M)
    np.testing.assert_allclose(P[:, 2], d[rows, cols], atol=1e-6)


def test_depth_shape_is_checked():
    with pytest.raises(InputError, match="depth"):
        depth_to_points(np.zeros((10, 10), np.float32), _camera())


def test_normals_of_a_tilted_plane_and_a_sphere():
    cam = _camera()
    rays = np.stack(np.meshgrid((np.arange(160) - 79.5) / 150, (np.arange(120) - 59.5) / 150), -1)
    n_true = np.array([0.3, -0.2, -1.0])
    n_true /= np.linalg.norm(n_true)
    # plane n . X = c with X = z (x, y, 1)
    c = n_true @ np.array([0, 0, 2.0])
    z = c / (rays[..., 0] * n_true[0] + rays[..., 1] * n_true[1] + n_true[2])
    N = normal_map(z.astype(np.float32), cam)
    ok = np.all(np.isfinite(N), -1)
    assert ok.mean() > 0.95
    assert _angle_deg(N[ok], n_true[None]).max() < NORMAL_TOLERANCE_DEG
    # sphere of radius 0.5 m at 2 m: normals point from the centre to the surface
    centre = np.array([0, 0, 2.0])
    dirs = np.concatenate([rays, np.ones((120, 160, 1))], -1)
    dn = dirs / np.linalg.norm(dirs, axis=-1, keepdims=True)
    bq = dn @ centre
    disc = bq ** 2 - (centre @ centre - 0.25)
    t = bq - np.sqrt(np.where(disc > 0, disc, np.nan))
    P = dn * t[..., None]
    zs = P[..., 2].astype(np.float32)
    N = normal_map(zs, cam)
    ok = np.all(np.isfinite(N), -1)
    expected = (P - centre) / 0.5
    assert ok.sum() > 1000
    assert np.median(_angle_deg(N[ok], expected[ok])) < SPHERE_NORMAL_TOLERANCE_DEG
    # no normal across the silhouette edge
    assert not ok[~np.isfinite(zs)].any()


def test_grid_normals_of_a_ramp():
    z = np.add.outer(np.zeros(8), 0.5 * np.arange(10) * 0.05) + 2.0   # dz/dx = 0.5
    n = grid_normals(z, 0.05)
    np.testing.assert_allclose(n[3, 4], np.array([0.5, 0, -1]) / np.linalg.norm([0.5, 0, -1]), atol=1e-9)
    np.testing.assert_allclose(n[0, 0], n[3, 4], atol=1e-9)   # one-sided at the border


def test_view_frame_is_gravity_aligned():
    cam = Camera.look_at("d", [0, 3, 1.5], [0, 0, 0.5], size=(64, 48), fov_x_deg=57)
    vf = ViewFrame.from_camera(cam)
    up_view = vf.from_world(np.array([[0, 0, 1.0], [0, 0, 0.0]]))
    np.testing.assert_allclose(up_view[0] - up_view[1], [0, -1, 0], atol=1e-12)
    assert vf.ground_y == pytest.approx(1.5)
    X = np.random.default_rng(1).normal(size=(5, 3))
    np.testing.assert_allclose(vf.to_world(vf.from_world(X)), X, atol=1e-12)
    np.testing.assert_allclose(vf.project(vf.from_world(X[:1] * 0 + [0, 0, 0.5])), cam.project([[0, 0, 0.5]]),
                               atol=1e-9)
    level = ViewFrame.from_camera(cam, pose_known=False)
    assert level.ground_y is None
    np.testing.assert_array_equal(level.view_from_cam, np.eye(3))


def test_principal_direction_of_an_elongated_cloud():
    rng = np.random.default_rng(2)
    P = rng.normal(size=(2000, 3)) * [0.1, 0.8, 0.05] + [1, 2, 3]
    c, axes, var = principal_direction(P)
    np.testing.assert_allclose(c, [1, 2, 3], atol=0.05)
    assert abs(axes[0] @ [0, 1, 0]) > 0.99 and axes[0][1] < 0      # signed upwards (view y is down)
    assert var[0] > var[1] > var[2]


def test_mask_from_background_matches_the_person(idle_sequence):
    seq = idle_sequence
    cam = seq.camera
    bg = BackgroundModel(seq.background)
    prev = None
    for t in range(0, seq.n_frames, 4):
        m = user_mask(seq.depth[t], cam, background=bg, previous=prev)
        gt = seq.subject[t] == 1
        iou = (m.mask & gt).sum() / (m.mask | gt).sum()
        assert m.found and iou > MIN_MASK_IOU
        prev = m.mask
    # without a background model the floor joins the person: the component is much larger
    m2 = user_mask(seq.depth[0], cam)
    assert m2.mask.sum() > 1.5 * (seq.subject[0] == 1).sum()


def test_mask_degenerate_inputs(idle_sequence):
    cam = idle_sequence.camera
    h, w = idle_sequence.depth.shape[1:]
    nan = np.full((h, w), np.nan, np.float32)
    assert not user_mask(nan, cam).found
    assert not user_mask(np.zeros((h, w), np.float32), cam).found
    tiny = nan.copy()
    tiny[10:12, 10:12] = 2.0
    assert not user_mask(tiny, cam).found                          # far below the minimum area
    given = np.zeros((h, w), bool)
    given[50:60, 50:60] = True
    m = user_mask(idle_sequence.depth[0], cam, given=given)
    assert m.mask.sum() <= 100 and not (m.mask & ~given).any()
    with pytest.raises(InputError, match="given mask"):
        user_mask(idle_sequence.depth[0], cam, given=given[:-1])


def test_mask_joins_a_hand_cut_off_by_a_shadow():
    cam = _camera()
    d = np.full((120, 160), np.nan, np.float32)
    d[30:110, 60:100] = 2.0             # body
    d[60:70, 104:112] = 1.8             # a hand 4 px away, nearer to the camera
    m = user_mask(d, cam, config=MaskConfig(min_area_m2=0.01))
    assert m.mask[65, 108] and m.mask[50, 80]


def test_user_cloud_statistics(idle_sequence):
    seq = idle_sequence
    vf = ViewFrame.from_camera(seq.camera)
    cloud = user_cloud(seq.depth[0], seq.subject[0] == 1, vf)
    assert cloud.n_points > 1000
    gt = vf.from_world(seq.joints13[0])
    # the centroid of a standing person's visible surface is near the hips, in front of them
    assert abs(cloud.centroid[0] - gt[[7, 8], 0].mean()) < 0.1
    assert cloud.principal_axis[1] < -0.9                            # vertical person
    assert not any(cloud.touches_border)
