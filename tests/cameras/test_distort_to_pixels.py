"""The NumPy lens model gives OpenCV's pixels: the same values as ``cv2.projectPoints``."""

import cv2
import numpy as np
import pytest

from toolkit.cameras import Camera, distort_to_pixels


def _opencv(pc, K, dist):
    uv, _ = cv2.projectPoints(pc.reshape(-1, 1, 3), np.zeros(3), np.zeros(3), K, dist)
    return uv.reshape(-1, 2)


@pytest.mark.parametrize("dist", [
    [-0.21, 0.09, 0.0011, -0.0023],
    [-0.21, 0.09, 0.0011, -0.0023, 0.031],
    [0.12, -0.05, 0.001, 0.002, 0.01, 0.05, -0.01, 0.002],
    [0.12, -0.05, 0.001, 0.002, 0.01, 0.05, -0.01, 0.002, 0.001, 0.002, -0.001, 0.0005],
    [0.12, -0.05, 0.001, 0.002, 0.01, 0.05, -0.01, 0.002, 0.001, 0.002, -0.001, 0.0005, 0.0, 0.0],
    [0.12, -0.05, 0.001, 0.002, 0.01, 0.05, -0.01, 0.002, 0.001, 0.002, -0.001, 0.0005, 0.01, -0.02],
])
def test_same_pixels_as_opencv(dist):
    rng = np.random.default_rng(3)
    pc = np.c_[rng.uniform(-1.2, 1.2, (5000, 2)), rng.uniform(0.3, 8.0, 5000)]
    K = np.array([[1510.0, 0.0, 955.5], [0.0, 1490.0, 541.25], [0.0, 0.0, 1.0]])
    d = np.array(dist, float)
    got = distort_to_pixels(pc, K, d)
    want = _opencv(pc, K, d)
    assert got.shape == (5000, 2)
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-9)


def test_camera_project_uses_it_and_keeps_nan_and_behind():
    cam = Camera.look_at("c", eye=(0.0, -6.0, 1.5), target=(0.0, 0.0, 1.0), size=(1920, 1080), fov_x_deg=60.0,
                         dist=[-0.2, 0.05, 0.001, 0.0, 0.0])
    rng = np.random.default_rng(4)
    pts = rng.uniform([-2, -2, 0], [2, 2, 2], (200, 3))
    pts[5] = np.nan
    pts[7] = cam.center + (cam.center - np.array([0.0, 0.0, 1.0]))  # behind the camera
    uv = cam.project(pts)
    assert np.isnan(uv[5]).all() and np.isnan(uv[7]).all()
    ok = np.isfinite(uv).all(1)
    want = _opencv(cam.to_cam(pts[ok]), cam.K, cam.dist)
    np.testing.assert_allclose(uv[ok], want, rtol=0, atol=1e-9)
