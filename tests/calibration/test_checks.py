"""The checks on constructed cases: cameras under the floor, a mirrored person, a board seen from behind,
left-handed scene coordinates."""

from __future__ import annotations

import numpy as np

from toolkit.anthropometry import BodyProportions
from toolkit.calibration.checks import (
    boards_seen_from_behind,
    cameras_under_floor,
    mirrored_person_warning,
    person_chirality,
    reprojection_summary,
)
from toolkit.calibration.extrinsics import extrinsics_from_scene_points
from toolkit.cameras import Camera, Rig
from toolkit.skeleton import JOINTS_14
from toolkit.synthetic.boards import board_pose


def rig_at(heights):
    return Rig(tuple(Camera.look_at(f"c{i}", [3 * np.cos(i), 3 * np.sin(i), h], [0, 0, 1.0], focal_px=500.0)
                     for i, h in enumerate(heights)))


def test_cameras_under_the_floor_warned():
    assert cameras_under_floor(rig_at([2.0, 1.5, 2.5])) == []
    w = cameras_under_floor(rig_at([2.0, -1.5, 2.5]))
    assert len(w) == 1 and "c1 at z = -1.50 m" in w[0] and "under the floor" in w[0]


def person(T=5):
    """A person facing +y (left at -x) with a nose in front of the ears: named 3D keypoints (T, 3)."""
    J = BodyProportions.from_height(1.75).rest_pose()
    named = {n: np.repeat(J[i][None], T, 0) for i, n in enumerate(JOINTS_14)}
    head = J[0]
    named["nose"] = np.repeat((head + [0, 0.1, 0])[None], T, 0)
    named["l_ear"] = np.repeat((head + [-0.07, 0, 0])[None], T, 0)
    named["r_ear"] = np.repeat((head + [0.07, 0, 0])[None], T, 0)
    return named


def test_mirrored_person_warned_and_true_person_not():
    p = person()
    assert np.all(person_chirality(p) == 1)
    assert mirrored_person_warning(p) == []
    mirrored = {k: v * [-1, 1, 1] for k, v in p.items()}  # reflection in the x = 0 plane
    assert np.all(person_chirality(mirrored) == -1)
    w = mirrored_person_warning(mirrored)
    assert len(w) == 1 and "mirrored" in w[0]


def test_chirality_unknown_without_a_front():
    p = {k: v for k, v in person().items() if k not in ("nose", "l_ear", "r_ear")}
    assert np.all(np.isnan(person_chirality(p)))
    assert mirrored_person_warning(p) == []


def test_board_seen_from_behind_warned():
    cam = Camera.look_at("c", [0, 0, 2.0], [0, 0, 0], up=(0, 1, 0), focal_px=500.0)
    front = board_pose([0, 0, 0], facing=(0, 0, -1))  # printed side up, the camera above
    back = board_pose([0, 0, 0], facing=(0, 0, 1))
    assert boards_seen_from_behind({("c", "v0"): cam.cam_from_world @ front}) == []
    w = boards_seen_from_behind({("c", "v1"): cam.cam_from_world @ back})
    assert len(w) == 1 and "c/v1" in w[0]


def test_left_handed_scene_points_warned():
    rng = np.random.default_rng(0)
    cams = [Camera.look_at(f"cam_{i}", [4 * np.cos(a), 4 * np.sin(a), 2.0], [0, 0, 1.0], size=(800, 600),
                           focal_px=700.0) for i, a in enumerate([0.2, 1.9, 3.6])]
    X = rng.uniform([-2, -2, 0], [2, 2, 1.5], (10, 3))
    px = np.stack([c.project(X) for c in cams])
    flipped = X * [1, 1, -1]  # the user's file has z pointing down
    r = extrinsics_from_scene_points([c.replace(cam_from_world=np.eye(4)) for c in cams], flipped, px)
    assert any("left-handed" in w for w in r.warnings)


def test_reprojection_summary():
    s = reprojection_summary(["a", "b"], np.array([0, 0, 1]), np.array([1.0, 3.0, 2.0]))
    assert s["a"]["n"] == 2 and s["a"]["median_px"] == 2.0 and np.isclose(s["a"]["rms_px"], np.sqrt(5))
    assert s["b"]["p95_px"] == 2.0


def test_mirrored_board_order_puts_cameras_under_the_floor():
    """Every camera's corners ordered mirrored (rows reversed): the board poses are seen from behind and the
    cameras end up under the floor; both are said, although the reprojection stays perfect."""
    from tests.calibration.test_extrinsics import board_views, intrinsics, true_rig
    from toolkit.calibration.boards import Board, BoardDetection
    from toolkit.calibration.extrinsics import extrinsics_from_boards

    cams = true_rig(3)
    board = Board("charuco", 5, 7, 0.08, 0.06)
    dets = board_views(cams, board, np.random.default_rng(7), n=6)
    mirrored = [{v: BoardDetection(d.source, d.size, d.ids,
                                   d.corners.reshape(board.rows, board.cols, 2)[::-1].reshape(-1, 2))
                 for v, d in cd.items()} for cd in dets]
    r = extrinsics_from_boards(intrinsics(cams), mirrored, board)
    assert max(v["rms_px"] for v in r.reprojection.values()) < 1e-6
    assert any("seen from behind" in w for w in r.warnings)
    assert any("under the floor" in w for w in r.warnings)


def test_mirrored_images_give_a_mirrored_person_warning():
    """Every camera's image flipped left-right (a selfie-mode video): the reconstruction is the mirror image
    of the person, which the chirality check says."""
    from toolkit.calibration.extrinsics import extrinsics_from_people
    from toolkit.skeleton.mappings import COCO_17
    from toolkit.synthetic.boards import people_sequence

    rng = np.random.default_rng(8)
    J = people_sequence(40, rng, height=1.75)[0]
    idx = {n: i for i, n in enumerate(JOINTS_14)}
    left = J[:, idx["l_shoulder"]] - J[:, idx["r_shoulder"]]
    left /= np.linalg.norm(left, axis=1, keepdims=True)
    front = np.cross(left, [0, 0, 1.0])
    head = J[:, idx["head"]]
    pts = {"nose": head + 0.1 * front, "left_eye": head + 0.08 * front + 0.03 * left,
           "right_eye": head + 0.08 * front - 0.03 * left, "left_ear": head + 0.07 * left,
           "right_ear": head - 0.07 * left}
    for side, s in (("left", "l"), ("right", "r")):
        for part in ("shoulder", "elbow", "wrist", "hip", "knee", "ankle"):
            pts[f"{side}_{part}"] = J[:, idx[f"{s}_{part}"]]
    P = np.stack([pts[n] for n in COCO_17], 1)
    cams = [Camera.look_at(f"cam_{i}", [4 * np.cos(a), 4 * np.sin(a), 2.0], [0, 0, 1.0], size=(801, 601),
                           focal_px=700.0) for i, a in enumerate([0.3, 1.9, 3.5, 5.0])]
    for flip, expect in ((False, False), (True, True)):
        kp = np.ones((4, 40, 17, 3))
        for c, cam in enumerate(cams):
            uv = cam.project(P)
            if flip:
                uv[..., 0] = cam.width - 1 - uv[..., 0]
            kp[c, ..., :2] = uv
        r = extrinsics_from_people([c.replace(cam_from_world=np.eye(4)) for c in cams], kp, COCO_17, "coco_17",
                                   height_m=1.75, rng=np.random.default_rng(0))
        assert any("mirrored solution" in w for w in r.warnings) == expect
