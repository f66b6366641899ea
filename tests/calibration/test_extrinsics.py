"""Extrinsics by the three methods on synthetic rigs with ground truth: exact without noise, close with noise."""

from __future__ import annotations

import numpy as np
import pytest

from toolkit.calibration.boards import Board, BoardDetection
from toolkit.calibration.extrinsics import (
    extrinsics_from_boards,
    extrinsics_from_people,
    extrinsics_from_scene_points,
    similarity_align,
)
from toolkit.cameras import Camera, Rig
from toolkit.errors import InputError
from toolkit.observe import RecordingObserver
from toolkit.skeleton import JOINTS_14
from toolkit.synthetic.boards import board_corners, board_pose, people_sequence

#: Without noise: camera centres (metres) and orientations (degrees) after alignment.
EXACT_CENTRE_M = 1e-6
EXACT_ANGLE_DEG = 1e-5
#: With 1 px keypoint / point noise on a 4 m rig.
NOISY_CENTRE_M = 0.03
NOISY_ANGLE_DEG = 0.3
#: People: the scale from the true stature (relative) and camera heights above the fitted floor (metres).
PEOPLE_SCALE_TOL = 0.03
PEOPLE_HEIGHT_TOL_M = 0.1


def true_rig(n=4) -> list[Camera]:
    cams = []
    for i in range(n):
        a = 2 * np.pi * i / n + 0.3
        cams.append(Camera.look_at(f"cam_{i + 1:02d}", [4 * np.cos(a), 4 * np.sin(a), 2.0 + 0.3 * i], [0, 0, 1.0],
                                   size=(800, 600), focal_px=700.0, dist=[-0.05, 0.01, 0, 0, 0]))
    return cams


def intrinsics(cams):
    return [c.replace(cam_from_world=np.eye(4)) for c in cams]


def pose_errors(est: Rig, true: list[Camera]):
    """Centre distances (m) and orientation angles (deg) after a similarity alignment, and its scale."""
    tc = Rig(tuple(true)).centers
    s, R, t = similarity_align(est.centers, tc)
    dc = np.linalg.norm(s * est.centers @ R.T + t - tc, axis=1)
    ang = []
    for ce, ct in zip(est, true):
        Rd = ct.R @ (ce.R @ R.T).T
        ang.append(np.degrees(np.arccos(np.clip((np.trace(Rd) - 1) / 2, -1, 1))))
    return dc, np.array(ang), s


def people_keypoints(cams, rng, noise_px, frames=60):
    P = people_sequence(frames, rng, height=1.75)[0]
    kp = np.zeros((len(cams), frames, 14, 3))
    for c, cam in enumerate(cams):
        uv = cam.project(P)
        kp[c, ..., :2] = uv + (rng.normal(0, noise_px, uv.shape) if noise_px else 0)
        kp[c, ..., 2] = 1.0
    return kp


@pytest.mark.parametrize("noise", [0.0, 1.0])
def test_people_recover_the_rig(noise):
    cams = true_rig()
    kp = people_keypoints(cams, np.random.default_rng(0), noise)
    obs = RecordingObserver()
    r = extrinsics_from_people(intrinsics(cams), kp, JOINTS_14, "skeleton14", height_m=1.75,
                               rng=np.random.default_rng(1), observer=obs)
    dc, ang, s = pose_errors(r.rig, cams)
    assert dc.max() < (EXACT_CENTRE_M * 100 if noise == 0 else NOISY_CENTRE_M)
    assert ang.max() < (EXACT_ANGLE_DEG * 100 if noise == 0 else NOISY_ANGLE_DEG)
    assert abs(s - 1) < PEOPLE_SCALE_TOL  # metric scale from the stature
    # the floor: camera heights as in the truth (feet on z = 0 there)
    assert np.abs(r.rig.centers[:, 2] - Rig(tuple(cams)).centers[:, 2]).max() < PEOPLE_HEIGHT_TOL_M
    assert not r.warnings
    assert "rig" in obs.kinds and "series" in obs.kinds


def test_people_without_height_warn_that_the_scale_is_assumed():
    cams = true_rig(3)
    kp = people_keypoints(cams, np.random.default_rng(2), 0.0, frames=40)
    r = extrinsics_from_people(intrinsics(cams), kp, JOINTS_14, "skeleton14", rng=np.random.default_rng(1))
    assert any("scale ambiguous" in w for w in r.warnings)


def test_people_with_too_few_keypoints_is_an_input_error():
    cams = true_rig(2)
    kp = np.zeros((2, 3, 14, 3))
    with pytest.raises(InputError, match="at least 8 keypoints"):
        extrinsics_from_people(intrinsics(cams), kp, JOINTS_14, "skeleton14")


@pytest.mark.parametrize("noise", [0.0, 1.0])
def test_scene_points_recover_the_rig(noise):
    cams = true_rig()
    rng = np.random.default_rng(3)
    X = rng.uniform([-2, -2, 0], [2, 2, 1.5], (12, 3))
    px = np.stack([c.project(X) for c in cams]) + (rng.normal(0, noise, (4, 12, 2)) if noise else 0)
    r = extrinsics_from_scene_points(intrinsics(cams), X, px)
    err = np.linalg.norm(r.rig.centers - Rig(tuple(cams)).centers, axis=1)  # no alignment: the points are the world
    assert err.max() < (EXACT_CENTRE_M if noise == 0 else NOISY_CENTRE_M)
    _, ang, _ = pose_errors(r.rig, cams)
    assert ang.max() < (EXACT_ANGLE_DEG if noise == 0 else NOISY_ANGLE_DEG)
    assert not r.warnings


def test_scene_point_misclicked_is_named():
    cams = true_rig()
    rng = np.random.default_rng(4)
    X = rng.uniform([-2, -2, 0], [2, 2, 1.5], (12, 3))
    px = np.stack([c.project(X) for c in cams]) + rng.normal(0, 0.3, (4, 12, 2))
    px[1, 5] += [40.0, -30.0]
    r = extrinsics_from_scene_points(intrinsics(cams), X, px, [f"P{i}" for i in range(12)])
    assert any("cam_02" in w and "P5" in w for w in r.warnings)


def board_views(cams, board, rng, n=10):
    dets = [{} for _ in cams]
    for v in range(n):
        if v == 0:
            Tb = board_pose([-0.3, -0.2, 0.0], facing=(0, 0, -1))  # on the floor, printed side up
        else:
            Tb = board_pose(rng.uniform([-0.5, -0.5, 0.0], [0.5, 0.5, 0.8]), rng.uniform(-30, 30, 2),
                            rng.uniform(-180, 180), facing=(0, 0, -1))
        for c, cam in enumerate(cams):
            uv = board_corners(cam, board, Tb)
            if np.all(cam.in_image(uv)) and Tb[:3, 2] @ (cam.center - Tb[:3, 3]) < 0:  # printed side visible
                dets[c][f"v{v:02d}"] = BoardDetection(f"v{v:02d}", cam.size, np.arange(board.n_corners), uv)
    return dets


@pytest.mark.parametrize("noise", [0.0, 0.5])
def test_board_seen_by_several_cameras_recovers_the_rig(noise):
    cams = true_rig()
    board = Board("charuco", 5, 7, 0.08, 0.06)
    rng = np.random.default_rng(5)
    dets = board_views(cams, board, rng)
    if noise:
        dets = [{v: BoardDetection(d.source, d.size, d.ids, d.corners + rng.normal(0, noise, d.corners.shape))
                 for v, d in cd.items()} for cd in dets]
    r = extrinsics_from_boards(intrinsics(cams), dets, board)
    dc, ang, s = pose_errors(r.rig, cams)
    assert dc.max() < (EXACT_CENTRE_M if noise == 0 else NOISY_CENTRE_M)
    assert ang.max() < (EXACT_ANGLE_DEG if noise == 0 else NOISY_ANGLE_DEG)
    assert abs(s - 1) < (1e-6 if noise == 0 else 0.01)  # the board's squares give the scale
    # the board of the first view lies on the floor: the cameras' heights are the true ones
    assert np.abs(r.rig.centers[:, 2] - Rig(tuple(cams)).centers[:, 2]).max() < (1e-6 if noise == 0 else 0.03)
    assert not r.warnings


def test_board_views_sharing_nothing_is_an_input_error():
    cams = true_rig(2)
    board = Board("charuco", 5, 7, 0.08, 0.06)
    dets = board_views(cams, board, np.random.default_rng(6), n=4)
    dets[1] = {f"other_{k}": d for k, d in dets[1].items()}
    with pytest.raises(InputError, match="share no view"):
        extrinsics_from_boards(intrinsics(cams), dets, board)


#: Issue 21's targets for extrinsics from the people on the Pose2Sim demo, against the lab's calibration.
REAL_CENTRE_M = 0.05
REAL_ANGLE_DEG = 1.0


@pytest.mark.slow
def test_pose2sim_demo_people_against_the_lab_calibration():
    import os
    from pathlib import Path

    from toolkit.io.calibration import read_calibration
    from toolkit.io.keypoint_files import camera_sources
    from toolkit.io.keypoint_formats import read_keypoints
    from toolkit.skeleton.mappings import KEYPOINTS

    root = Path(os.environ.get("TOOLKIT_REALDATA", Path(__file__).resolve().parents[3] / "shared" / "realdata"))
    root = root / "pose2sim_demo"
    if not root.is_dir():
        pytest.skip(f"real data not found at {root}")
    lab = read_calibration(root / "S00_Calibration" / "Calib_qualisys.toml")
    trial = root / "S00_P00_SingleParticipant" / "S00_P00_T01_BalancingTrial"
    data = read_keypoints(camera_sources(trial / "pose-associated"), "body_25b")
    r = extrinsics_from_people(intrinsics(list(lab)), data.keypoints, KEYPOINTS["body_25b"], "body_25b",
                               height_m=1.72, rng=np.random.default_rng(0))
    dc, ang, s = pose_errors(r.rig, list(lab))
    assert dc.max() < REAL_CENTRE_M and ang.max() < REAL_ANGLE_DEG
    assert abs(s - 1) < 0.07  # stature priors on OpenPose joints: 3.7 % measured
    assert not any("under the floor" in w or "mirrored" in w for w in r.warnings)
