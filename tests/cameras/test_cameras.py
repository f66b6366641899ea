"""Projection, back-projection, triangulation and plane homographies."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from toolkit.cameras import (Camera, Rig, closest_point_to_rays, plane_homography, reprojection_errors,
                             triangulate_linear, triangulate_rays)
from toolkit.errors import InputError

#: Exact recovery tolerance (double precision, well-conditioned rigs).
EXACT_M = 1e-7
#: Pixel noise used in the noisy tests and the bound on the resulting 3D error:
#: with cameras ~5 m away and f ~ 1000 px, 1 px is ~5 mm, so 4 sigma ~ 2-3 cm.
NOISE_PX = 1.0
NOISY_BOUND_M = 0.03


def ring_rig(n=4, radius=5.0, dist=None) -> Rig:
    cams = []
    for i in range(n):
        a = 2 * np.pi * i / n
        eye = [radius * np.cos(a), radius * np.sin(a), 1.5 + 0.3 * i]
        cams.append(Camera.look_at(f"c{i}", eye, [0, 0, 1], size=(1280, 720), focal_px=1000.0, dist=dist))
    return Rig(tuple(cams))


@pytest.fixture
def points():
    rng = np.random.default_rng(0)
    return rng.uniform([-1, -1, 0], [1, 1, 2], (50, 3))


def test_projection_matches_opencv(points):
    cam = ring_rig(dist=[0.05, -0.02, 0.001, 0.002, 0.0])[1]
    uv = cam.project(points)
    ref, _ = cv2.projectPoints(points, cam.rvec, cam.t, cam.K, cam.dist)
    np.testing.assert_allclose(uv, ref.reshape(-1, 2), atol=1e-9)


@pytest.mark.parametrize("dist", [None, [0.08, -0.03, 0.001, -0.002, 0.005]])
def test_rays_pass_through_points(points, dist):
    cam = ring_rig(dist=dist)[0]
    o, d = cam.rays(cam.project(points))
    diff = points - o
    off = diff - (diff * d).sum(-1, keepdims=True) * d
    assert np.abs(np.linalg.norm(d, axis=-1) - 1).max() < 1e-12
    assert np.linalg.norm(off, axis=-1).max() < 1e-6


def test_backproject_inverts_project(points):
    cam = ring_rig(dist=[0.05, 0.01, 0, 0, 0])[2]
    X = cam.backproject(cam.project(points), cam.depth_of(points))
    np.testing.assert_allclose(X, points, atol=1e-6)


def test_behind_camera_and_nan_are_nan():
    cam = ring_rig()[0]
    behind = cam.center - 2 * cam.forward
    uv = cam.project(np.array([behind, [np.nan, 0, 0]]))
    assert np.isnan(uv).all()


@pytest.mark.parametrize("method", ["linear", "rays"])
def test_triangulation_exact(points, method):
    rig = ring_rig()
    obs = rig.project(points)
    X = triangulate_linear(rig, obs) if method == "linear" else triangulate_rays(rig, obs)[0]
    assert np.abs(X - points).max() < EXACT_M


@pytest.mark.parametrize("method", ["linear", "rays"])
def test_triangulation_noise_bounded(points, method):
    rig = ring_rig()
    rng = np.random.default_rng(1)
    obs = rig.project(points) + rng.normal(0, NOISE_PX, (len(rig), len(points), 2))
    X = triangulate_linear(rig, obs) if method == "linear" else triangulate_rays(rig, obs)[0]
    err = np.linalg.norm(X - points, axis=-1)
    assert err.max() < NOISY_BOUND_M
    assert np.median(reprojection_errors(rig, X, obs)) < 2 * NOISE_PX


def test_triangulation_missing_views(points):
    rig = ring_rig()
    obs = rig.project(points)
    obs[0, :10] = np.nan          # one view missing: still triangulated
    obs[1:, 10:15] = np.nan       # only one view left: NaN
    X, dist = triangulate_rays(rig, obs)
    assert np.abs(X[:10] - points[:10]).max() < EXACT_M
    assert np.isnan(X[10:15]).all()
    assert np.isnan(dist[0, :10]).all()
    XL = triangulate_linear(rig, obs)
    assert np.isnan(XL[10:15]).all() and np.abs(XL[:10] - points[:10]).max() < EXACT_M


def test_closest_point_distances():
    o = np.array([[0, 0, 0], [0, 1, 0]], float)
    d = np.array([[1, 0, 0], [1, 0, 0.0]])
    X, dist = closest_point_to_rays(o, d)
    assert np.isnan(X).all()  # parallel rays: no unique point
    o = np.array([[0, 0, 0], [0, 0, 1.0]])
    d = np.array([[1, 0, 0], [0, 1, 0.0]])
    X, dist = closest_point_to_rays(o, d)
    np.testing.assert_allclose(X, [0, 0, 0.5], atol=1e-12)
    np.testing.assert_allclose(dist, [0.5, 0.5], atol=1e-12)


def test_plane_homography_maps_plane_points():
    rig = ring_rig()
    n = np.array([0.2, -0.3, 1.0])
    p0 = np.array([0.1, 0.2, 0.9])
    rng = np.random.default_rng(3)
    a = np.cross(n, [1, 0, 0])
    b = np.cross(n, a)
    pts = p0 + rng.uniform(-0.5, 0.5, (20, 1)) * a / np.linalg.norm(a) + rng.uniform(-0.5, 0.5, (20, 1)) * b / np.linalg.norm(b)
    H = plane_homography(rig[0], rig[1], n, p0)
    src = rig[0].project(pts)
    dst = cv2.perspectiveTransform(src.reshape(-1, 1, 2), H).reshape(-1, 2)
    np.testing.assert_allclose(dst, rig[1].project(pts), atol=1e-6)


def test_scaled_camera_consistent(points):
    cam = ring_rig()[0]
    half = cam.scaled(0.5)
    uv, uv2 = cam.project(points), half.project(points)
    np.testing.assert_allclose((uv + 0.5) * 0.5 - 0.5, uv2, atol=1e-9)


@pytest.mark.parametrize("kwargs, field", [
    (dict(K=np.eye(2)), "K"),
    (dict(K=np.diag([-1.0, 1, 1])), "K"),
    (dict(dist=[0.1, 0.2, 0.3]), "dist"),
    (dict(cam_from_world=np.diag([1.0, 1, -1, 1])), "cam_from_world"),
    (dict(size=(0, 10)), "size"),
])
def test_bad_camera_raises(kwargs, field):
    base = dict(name="bad", K=np.diag([100.0, 100, 1]), dist=np.zeros(5), size=(64, 48), cam_from_world=np.eye(4))
    base.update(kwargs)
    with pytest.raises(InputError, match=field):
        Camera(**base)


def test_bad_shapes_raise():
    rig = ring_rig()
    with pytest.raises(InputError, match="points2d"):
        triangulate_rays(rig, np.zeros((3, 5, 2)))
    with pytest.raises(InputError, match="points_world"):
        rig[0].project(np.zeros((5, 2)))
    with pytest.raises(InputError, match="unique"):
        Rig((rig[0], rig[0]))
