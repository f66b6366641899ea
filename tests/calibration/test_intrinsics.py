"""Intrinsics from a board: exact recovery, rendered images, rejection, coverage, wrong declared size, real data."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

from toolkit.calibration.boards import Board, BoardDetection, board_frames, detect_board, detect_in_frames
from toolkit.calibration.intrinsics import calibrate_intrinsics, coverage
from toolkit.cameras import Camera
from toolkit.errors import InputError
from toolkit.io.calibration import read_calibration
from toolkit.synthetic.boards import board_corners, pixel_rays, random_board_poses, render_checkerboard

REPO_ROOT = Path(__file__).resolve().parents[2]
#: Exact corners: relative error of fx, fy, cx, cy.
EXACT_REL_TOL = 1e-6
#: Rendered images (detector noise ~0.1 px): relative focal error.
RENDERED_FOCAL_TOL = 0.01
#: Exact corners: absolute error of the distortion terms (OpenCV works in float32 corners).
EXACT_DIST_TOL = 1e-5
#: Real data target of issue 21: focal within 2 % of the lab's calibration.
REAL_FOCAL_TOL = 0.02

K_TRUE = np.array([[420.0, 0, 163.0], [0, 423.0, 118.0], [0, 0, 1]])
DIST_TRUE = np.array([-0.12, 0.03, 0.0008, -0.0005, 0.0])


def camera(size=(320, 240)) -> Camera:
    return Camera.look_at("cam", [0, 0, 0], [0, 1, 0], size=size, focal_px=420.0, dist=DIST_TRUE).replace(K=K_TRUE)


def exact_detections(cam, board, poses):
    return [BoardDetection(f"v{i}", cam.size, np.arange(board.n_corners), board_corners(cam, board, T))
            for i, T in enumerate(poses)]


def test_exact_recovery_without_noise():
    cam, board = camera(), Board("checkerboard", 5, 7, 0.03)
    poses = random_board_poses(cam, board, 12, np.random.default_rng(1), distance=(0.4, 0.8))
    r = calibrate_intrinsics(exact_detections(cam, board, poses), board, "cam")
    K = r.camera.K
    for a, b in ((K[0, 0], 420.0), (K[1, 1], 423.0), (K[0, 2], 163.0), (K[1, 2], 118.0)):
        assert abs(a / b - 1) < EXACT_REL_TOL
    assert np.allclose(r.camera.dist[:4], DIST_TRUE[:4], atol=EXACT_DIST_TOL)
    assert r.rms_px < 1e-4 and not r.rejected


def test_rendered_images_detected_and_calibrated():
    cam, board = camera(), Board("checkerboard", 5, 7, 0.03)
    poses = random_board_poses(cam, board, 8, np.random.default_rng(2), distance=(0.4, 0.8))
    rays = pixel_rays(cam)
    dets = []
    for i, T in enumerate(poses):
        d = detect_board(render_checkerboard(cam, board, T, rays=rays), board, f"v{i}")
        assert d is not None
        dets.append(d)
    r = calibrate_intrinsics(dets, board, "cam")
    assert abs(r.camera.K[0, 0] / 420.0 - 1) < RENDERED_FOCAL_TOL
    assert abs(r.camera.K[1, 1] / 423.0 - 1) < RENDERED_FOCAL_TOL
    assert r.rms_px < 0.5


def test_bad_view_rejected_with_reason():
    cam, board = camera(), Board("checkerboard", 5, 7, 0.03)
    poses = random_board_poses(cam, board, 10, np.random.default_rng(3), distance=(0.4, 0.8))
    dets = exact_detections(cam, board, poses)
    rng = np.random.default_rng(4)
    bad = dets[4].corners + rng.normal(0, 6.0, dets[4].corners.shape)  # a wrong detection
    dets[4] = BoardDetection("bad_view", cam.size, dets[4].ids, bad)
    r = calibrate_intrinsics(dets, board, "cam")
    assert [s for s, _ in r.rejected] == ["bad_view"]
    assert "RMS error" in r.rejected[0][1]
    assert abs(r.camera.K[0, 0] / 420.0 - 1) < EXACT_REL_TOL * 10


def test_board_only_in_the_centre_warns_about_coverage():
    cam, board = camera(), Board("checkerboard", 3, 4, 0.01)
    rng = np.random.default_rng(5)
    poses = []
    while len(poses) < 8:
        T = random_board_poses(cam, board, 1, rng, distance=(0.6, 0.8), max_tilt_deg=35)[0]
        if np.all(np.abs(board_corners(cam, board, T) - [160, 120]).max(0) < [70, 50]):
            poses.append(T)
    r = calibrate_intrinsics(exact_detections(cam, board, poses), board, "cam")
    assert r.coverage <= 0.25
    assert any("reaches only" in w for w in r.warnings)
    assert coverage(np.array([[0, 0], [319, 239]]), (320, 240), 2) == 0.5


def test_wrong_declared_board_size_is_said_so(tmp_path):
    cam, board = camera(), Board("checkerboard", 5, 7, 0.03)
    T = random_board_poses(cam, board, 1, np.random.default_rng(6), distance=(0.4, 0.6), max_tilt_deg=15)[0]
    img = render_checkerboard(cam, board, T)
    declared = Board("checkerboard", 4, 7, 0.03)
    with pytest.raises(InputError, match="5x7 inner corners.*not 4x7 as declared"):
        detect_in_frames([("view.png", img)], declared, str(tmp_path))


def test_folder_without_images_is_an_error(tmp_path):
    with pytest.raises(InputError, match="images"):
        list(board_frames(tmp_path))


def test_pose2sim_demo_intrinsics_focal_within_two_percent():
    root = Path(os.environ.get("TOOLKIT_REALDATA", REPO_ROOT.parent / "shared" / "realdata")) / "pose2sim_demo"
    if not root.is_dir():
        pytest.skip(f"real data not found at {root}")
    calib = root / "S00_Calibration"
    ref = read_calibration(calib / "Calib_qualisys.toml")["cam_02"]
    board = Board("checkerboard", 4, 7, 0.060)
    folder = calib / "intrinsics" / "int_cam02_img"
    dets, missed = detect_in_frames(board_frames(folder), board, str(folder))
    r = calibrate_intrinsics(dets, board, "cam_02", missed=missed)
    assert abs(r.camera.K[0, 0] / ref.K[0, 0] - 1) < REAL_FOCAL_TOL
    assert abs(r.camera.K[1, 1] / ref.K[1, 1] - 1) < REAL_FOCAL_TOL
    assert r.camera.size == (1088, 1920)
    assert len(r.rejected) >= 1  # one image shows the board cut by the image border


def charuco_image(board_shown: Board, seed: int = 0):
    from toolkit.synthetic.boards import render_charuco

    cam = Camera.look_at("cam", [0, 0, 0], [0, 1, 0], size=(640, 480), focal_px=500.0)
    T = random_board_poses(cam, board_shown, 1, np.random.default_rng(seed), distance=(0.5, 0.7))[0]
    return cam, T, render_charuco(cam, board_shown, T)


def test_charuco_detected_at_the_right_corners():
    board = Board("charuco", 5, 7, 0.04, 0.03)
    cam, T, img = charuco_image(board)
    d = detect_board(img, board)
    assert d is not None and len(d.ids) >= 30
    assert np.abs(d.corners - board_corners(cam, board, T)[d.ids]).max() < 1.5  # warped, not rendered exactly


@pytest.mark.parametrize("declared, message", [
    (Board("charuco", 4, 7, 0.04, 0.03), "5x7 inner corners, not 4x7 as declared"),
    (Board("charuco", 5, 7, 0.04, 0.02), "markers measure 29 mm .* not 20 mm as declared"),
    (Board("charuco", 5, 7, 0.04, 0.03, "DICT_5X5_50"), "markers of DICT_4X4_50: check --dictionary"),
])
def test_charuco_declared_wrong_is_said_so(declared, message):
    _, _, img = charuco_image(Board("charuco", 5, 7, 0.04, 0.03))
    with pytest.raises(InputError, match=message):
        detect_in_frames([("view.png", img)], declared, "images")
