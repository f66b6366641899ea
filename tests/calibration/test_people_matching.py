"""Calibration from several people whose detections are not associated across cameras (issue 32 item 5).

Synthetic: two people walking through a 4-camera rig and a bystander seen by one camera.  Each
camera lists its detections in its own order, or keeps one person per frame that is not the same
person in every camera (what "the most confident person of each camera" gives on real footage):
the rig is recovered exactly, and the matching puts the detections of one person together.
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from toolkit.calibration.extrinsics import extrinsics_from_people
from toolkit.calibration.people_matching import (
    associate_detections,
    detections_array,
    match_camera_pair,
    triangulate_normalised,
)
from toolkit.errors import InputError
from toolkit.skeleton import JOINTS_14
from toolkit.synthetic.boards import people_sequence

from .test_extrinsics import (
    EXACT_ANGLE_DEG,
    EXACT_CENTRE_M,
    NOISY_ANGLE_DEG,
    NOISY_CENTRE_M,
    intrinsics,
    pose_errors,
    true_rig,
)

#: Frames of the synthetic scenes (enough for the rig, few for speed).
N_FRAMES = 40
#: A detection's median error against its group, pixels (exact projections: numerical noise only).
EXACT_GROUP_PX = 1e-6


def scene(rng: np.random.Generator, noise_px: float = 0.0):
    """Two people seen by all 4 cameras and a bystander seen by camera 0 only.

    Returns the cameras, the people's joints (2, T, 14, 3) and per camera and frame its detections
    (n_cams, T, 3, 14, 3) in a random order per camera and frame (slot 2 of cameras 1-3 empty), and
    that order: ``order[c, t, k]`` is the slot of person k (2: the bystander).
    """
    cams = true_rig()
    people = people_sequence(N_FRAMES, rng, height=1.75, radius=1.5, n_people=3)  # person 2: the bystander
    kp = np.full((len(cams), N_FRAMES, 3, 14, 3), np.nan)
    kp[..., 2] = 0.0
    order = np.zeros((len(cams), N_FRAMES, 3), int)
    for c, cam in enumerate(cams):
        for t in range(N_FRAMES):
            who = [0, 1, 2] if c == 0 else [0, 1]
            slots = rng.permutation(len(who))
            for k, s in zip(who, slots):
                uv = cam.project(people[k, t])
                kp[c, t, s, :, :2] = uv + (rng.normal(0, noise_px, uv.shape) if noise_px else 0)
                kp[c, t, s, :, 2] = 1.0
                order[c, t, k] = s
    return cams, people, kp, order


def test_triangulation_is_exact_on_exact_projections():
    cams = true_rig()
    X = np.random.default_rng(0).uniform([-1, -1, 0], [1, 1, 2], (5, 3))
    xy = np.stack([cam.undistort_points(cam.project(X)) for cam in cams])
    xy[1, 0] = np.nan  # a point seen by three cameras still triangulates
    xy[1:, 4] = np.nan  # a point seen by one camera does not
    out = triangulate_normalised(np.stack([c.cam_from_world for c in cams]), xy)
    np.testing.assert_allclose(out[:4], X[:4], atol=1e-9)
    assert np.isnan(out[4]).all()


def test_detections_array_pads_frames_and_people():
    a = SimpleNamespace(frames=np.array([0, 1]), people=[np.ones((2, 14, 3)), np.zeros((0, 14, 3))])
    b = SimpleNamespace(frames=np.array([1]), people=[np.full((1, 14, 3), 2.0)])
    out = detections_array([a, b], [0, 1], 14)
    assert out.shape == (2, 2, 2, 14, 3)
    assert np.all(out[0, 0, :, :, 0] == 1) and np.isnan(out[0, 1, :, :, 0]).all() and np.all(out[0, 1, ..., 2] == 0)
    assert np.isnan(out[1, 0, ..., 0]).all() and np.all(out[1, 1, 0, :, 0] == 2) and np.isnan(out[1, 1, 1, :, 0]).all()
    with pytest.raises(InputError, match="shape"):
        detections_array([SimpleNamespace(frames=np.array([0]), people=[np.ones((1, 13, 3))])], [0], 14)


def test_a_camera_pair_matches_the_same_person_and_leaves_the_bystander():
    rng = np.random.default_rng(3)
    cams, _, kp, order = scene(rng)
    xy = np.stack([c.undistort_points(kp[i, ..., :2]) for i, c in enumerate(intrinsics(cams))])
    seen = kp[..., 2] > 0
    m = match_camera_pair(xy, seen, 0, 1, (700.0, 700.0), 4.0, 10.0, rng)
    assert m is not None and len(m.frames) == 2 * N_FRAMES  # both people in every frame
    person_in_0 = np.argmax(order[0, m.frames] == m.det_a[:, None], axis=1)
    person_in_1 = np.argmax(order[1, m.frames] == m.det_b[:, None], axis=1)
    assert np.array_equal(person_in_0, person_in_1) and np.all(person_in_0 < 2)


def test_calibrated_association_groups_each_person_once():
    rng = np.random.default_rng(4)
    cams, _, kp, order = scene(rng)
    xy = np.stack([c.undistort_points(kp[i, ..., :2]) for i, c in enumerate(cams)])
    groups, frames, err = associate_detections(np.stack([c.cam_from_world for c in cams]), xy, kp[..., 2] > 0,
                                               np.full(4, 700.0), 10.0)
    assert len(groups) == 2 * N_FRAMES and np.all(groups >= 0)  # two people, all four cameras, no bystander
    assert err.max() < EXACT_GROUP_PX
    for g, t in zip(groups, frames):
        k = int(np.flatnonzero(order[0, t] == g[0])[0])
        assert all(order[c, t, k] == g[c] for c in range(4))


@pytest.mark.parametrize("noise", [0.0, 1.0])
def test_every_detection_in_any_order_recovers_the_rig(noise):
    cams, _, kp, _ = scene(np.random.default_rng(5), noise)
    r = extrinsics_from_people(intrinsics(cams), kp, JOINTS_14, "skeleton14", height_m=1.75,
                               rng=np.random.default_rng(1))
    dc, ang, s = pose_errors(r.rig, cams)
    assert dc.max() < (EXACT_CENTRE_M * 100 if noise == 0 else NOISY_CENTRE_M)
    assert ang.max() < (EXACT_ANGLE_DEG * 100 if noise == 0 else NOISY_ANGLE_DEG)
    assert r.details["groups"] == 2 * N_FRAMES and r.details["groups_by_views"] == {4: 2 * N_FRAMES}
    assert r.details["detections_unmatched"] == N_FRAMES  # the bystander, every frame
    assert not any("under the floor" in w or "mirrored" in w for w in r.warnings)


def test_one_person_per_camera_that_differs_between_cameras_recovers_the_rig():
    """Each camera keeps one person per frame, and in half the frames cameras 0, 1 keep another one than
    cameras 2, 3: those frames give two groups of two cameras (one per person), never one of four."""
    rng = np.random.default_rng(6)
    cams, _, kp, order = scene(rng)
    one = np.full(kp.shape[:2] + kp.shape[3:], np.nan)
    one[..., 2] = 0.0
    for c in range(4):
        for t in range(N_FRAMES):
            k = 1 if (t % 2 and c < 2) else 0
            one[c, t] = kp[c, t, order[c, t, k]]
    r = extrinsics_from_people(intrinsics(cams), one, JOINTS_14, "skeleton14", height_m=1.75,
                               rng=np.random.default_rng(1))
    dc, ang, _ = pose_errors(r.rig, cams)
    assert dc.max() < EXACT_CENTRE_M * 100 and ang.max() < EXACT_ANGLE_DEG * 100
    assert r.details["groups_by_views"] == {2: N_FRAMES, 4: N_FRAMES // 2}
