"""Association of detections across views and over time (toolkit.multiview.association / tracking)."""

from __future__ import annotations

import numpy as np
import pytest

from toolkit.anthropometry import BodyProportions
from toolkit.cameras import Camera, Rig
from toolkit.errors import InputError
from toolkit.motion import generate_motion
from toolkit.multiview.association import AssociationConfig, associate_frame, pair_ray_distances
from toolkit.multiview.tracking import TrackingConfig, frame_detections, main_person, track_people
from toolkit.synthetic.crowd import detect_crowd, make_crowd, score_people

#: Exact projections: the rays of one person meet to rounding.
EXACT_RAY_M = 1e-6
#: Two people 1.2 m apart seen by cameras at one height: the rays of one pass the other's at
#: 5-7 cm (measured; joints at one height lie in one epipolar plane, which is why the lowest
#: ray distance, a third view and tracking decide, not a threshold alone).
OTHER_PERSON_RAY_M = 0.03
#: Raw association triangulation (no offsets, closest points) of the crowd scenes with detector
#: noise (3 px bias, 1.5 px jitter at 200 px) and 4 px calibration error: measured 18-45 mm.
CROWD_RAW_MPJPE_M = 0.07


def _two_people(n_frames=1):
    props = BodyProportions.from_height(1.75)
    a = generate_motion("idle", props, n_frames, 25.0, rng=0)
    b = generate_motion("wave", BodyProportions.from_height(1.6), n_frames, 25.0, rng=1)
    a = a - np.r_[np.mean(a[:, :, :2], axis=(0, 1)), 0] + np.array([0.6, 0.0, 0.0])
    b = b - np.r_[np.mean(b[:, :, :2], axis=(0, 1)), 0] + np.array([-0.6, 0.2, 0.0])
    return a, b


def _ring(n=3, radius=5.0):
    return Rig(tuple(Camera.look_at(f"cam{i}", [radius * np.cos(t), radius * np.sin(t), 2.0], [0, 0, 0.9],
                                    size=(1280, 720), focal_px=700.0)
                     for i, t in enumerate(np.linspace(0, 2 * np.pi, n, endpoint=False) + 0.3)))


def _detect(cam, joints):
    return np.concatenate([cam.project(joints), np.full((len(joints), 1), 0.9)], axis=1)


def test_pair_ray_distances_exact_and_apart():
    rig = _ring()
    a, b = _two_people()
    da = np.stack([_detect(rig[0], a[0]), _detect(rig[0], b[0])])
    db = np.stack([_detect(rig[1], b[0]), _detect(rig[1], a[0])])
    D = pair_ray_distances(rig[0], da, rig[1], db)
    assert D.shape == (2, 2)
    assert D[0, 1] < EXACT_RAY_M and D[1, 0] < EXACT_RAY_M
    assert D[0, 0] > OTHER_PERSON_RAY_M and D[1, 1] > OTHER_PERSON_RAY_M


def test_too_few_shared_keypoints_is_no_affinity():
    rig = _ring()
    a, _ = _two_people()
    da, db = _detect(rig[0], a[0])[None], _detect(rig[1], a[0])[None]
    db[0, 3:, 2] = 0.0  # three keypoints left
    assert np.isinf(pair_ray_distances(rig[0], da, rig[1], db, min_shared=4)).all()


def test_associate_frame_groups_people_and_leaves_one_view_bystander():
    rig = _ring(4)
    a, b = _two_people()
    by = generate_motion("idle", BodyProportions.from_height(1.8), 1, 25.0, rng=3)[0]
    by = by - np.r_[by[:, :2].mean(0), 0] + np.r_[0.5 * (rig[0].center[:2]), 0]  # half-way to camera 0
    dets = []
    for v, cam in enumerate(rig):
        d = [_detect(cam, b[0]), _detect(cam, a[0])] if v % 2 else [_detect(cam, a[0]), _detect(cam, b[0])]
        if v == 0:
            d.append(_detect(cam, by))  # seen (detected) by camera 0 only
        dets.append(np.stack(d))
    fa = associate_frame(dets, rig)
    assert fa.n_people == 2
    truth = {tuple(np.array([0, 1, 0, 1])), tuple(np.array([1, 0, 1, 0]))}
    assert {tuple(g) for g in fa.groups} == truth
    assert fa.unassigned == ((0, 2),)
    assert (fa.cost < EXACT_RAY_M).all()
    for g, X in zip(fa.groups, fa.joints3d):
        true = a[0] if g[0] == 0 else b[0]
        assert np.abs(X - true).max() < 1e-6


def test_group_outside_the_capture_volume_is_not_a_person():
    """Someone behind two cameras of four, seen (and detected) by those two only."""
    rig = _ring(4)
    a, _ = _two_people()
    mid = rig[2].center[:2] + rig[3].center[:2]
    behind = a[0] - np.r_[a[0, :, :2].mean(0), 0] + np.r_[7.0 * mid / np.linalg.norm(mid), 0]  # behind cams 2, 3
    seen = [v for v, cam in enumerate(rig)
            if (cam.depth_of(behind) > 0).all() and cam.in_image(cam.project(behind)).all()]
    assert len(seen) == 2  # the set-up: two cameras see it
    dets = [np.stack([_detect(cam, behind)]) if v in seen else np.zeros((0, 14, 3)) for v, cam in enumerate(rig)]
    assert associate_frame(dets, rig).n_people == 0
    assert associate_frame(dets, rig, AssociationConfig(capture_volume_share=0.0)).n_people == 1


@pytest.mark.parametrize("bad", ["views", "shape", "keypoints"])
def test_bad_detections_raise(bad):
    rig = _ring()
    ok = np.zeros((1, 14, 3))
    dets = {"views": [ok, ok], "shape": [ok, ok, np.zeros((14, 3))],
            "keypoints": [ok, ok, np.zeros((1, 13, 3))]}[bad]
    with pytest.raises(InputError):
        associate_frame(dets, rig)


def test_bad_config_raises():
    with pytest.raises(InputError):
        AssociationConfig(max_ray_distance_m=0.0)
    with pytest.raises(InputError):
        AssociationConfig(min_views=1)
    with pytest.raises(InputError):
        TrackingConfig(fps=0.0)


@pytest.mark.parametrize("seed", [0, 1])
def test_crowd_tracked_without_switches_and_bystanders(seed):
    """Three people entering and leaving, two bystanders each seen by one camera, detector noise."""
    scene = make_crowd(3, 2, 4, 30, 25.0, 4.0, rng=seed)
    det = detect_crowd(scene, rng=seed)
    assert len(np.unique(det.counts())) > 1  # views hold different counts
    tracks = track_people(det.detections, scene.measured_rig, TrackingConfig(fps=scene.fps))
    score = score_people(tracks.joints3d, scene, det)
    assert tracks.n_people == 3
    assert score.false_people == 0
    assert (score.switches == 0).all()
    assert (score.missed <= 1).all()
    assert (score.mpjpe_m < CROWD_RAW_MPJPE_M).all()
    # each person's keypoints come from its own detections only
    for k in range(tracks.n_people):
        ids = {int(det.identity[t][v][i]) for t, v in zip(*np.nonzero(tracks.assignment[k] >= 0))
               for i in [tracks.assignment[k, t, v]]}
        assert len(ids) == 1 and scene.roles[ids.pop()] == "person"


def test_main_person_is_the_one_most_cameras_agree_on():
    """A bystander detected more confidently, by one camera, is not the person."""
    rig = _ring(3)
    a, _ = _two_people(5)
    by = a - np.r_[a[0, :, :2].mean(0), 0] + np.r_[0.4 * rig[0].center[:2], 0]
    frames = []
    for t in range(5):
        fr = []
        for v, cam in enumerate(rig):
            d = _detect(cam, a[t])
            d[:, 2] = 0.5
            if v == 0:
                fr.append(np.stack([_detect(cam, by[t]), d]))  # the bystander first and more confident
            else:
                fr.append(d[None])
        frames.append(fr)
    kp = main_person(frames, rig, TrackingConfig(fps=25.0, min_frames=1))
    assert kp.shape == (3, 5, 14, 3)
    assert np.allclose(kp[0, :, :, :2], np.stack([rig[0].project(a[t]) for t in range(5)]))


def test_frame_detections_aligns_cameras_on_frame_numbers():
    class Cam:
        def __init__(self, frames, people):
            self.frames, self.people = np.array(frames), people

    p = np.ones((1, 14, 3))
    out = frame_detections([Cam([0, 2], [p, 2 * p]), Cam([1], [3 * p])], np.array([0, 1, 2]), 14)
    assert [[len(d) for d in fr] for fr in out] == [[1, 0], [0, 1], [1, 0]]
    assert out[2][0][0, 0, 0] == 2.0


def test_ghost_of_two_one_view_bystanders_is_dropped():
    """Seed 0: the rays of two bystanders, each seen by one camera, meet frame after frame in a small
    floating figure the other cameras do not show; it is a person only without that rule."""
    scene = make_crowd(3, 2, 4, 30, 25.0, 4.0, rng=0)
    det = detect_crowd(scene, rng=0)
    loose = track_people(det.detections, scene.measured_rig,
                         TrackingConfig(fps=scene.fps, max_unexplained_share=1.0))
    assert score_people(loose.joints3d, scene, det).false_people == 1
    tracks = track_people(det.detections, scene.measured_rig, TrackingConfig(fps=scene.fps))
    assert score_people(tracks.joints3d, scene, det).false_people == 0
    ghost = [fa.unexplained for fa in tracks.frames if len(fa.unexplained)]
    assert max(int(u.max()) for u in ghost) >= 1
