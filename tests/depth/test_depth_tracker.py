"""The depth tracker on synthetic depth with ground truth: accuracy, states, constraints, bad input."""

from __future__ import annotations

import numpy as np
import pytest
from tests.depth.conftest import make_sequence, mpjpe

from toolkit.depth.constraints import ConstraintConfig, constraint_violations
from toolkit.body.control_points import BodyDimensions
from toolkit.depth.tracker import LOST, RECOVERING, TRACKING, DepthTracker, TrackerConfig
from toolkit.errors import InputError
from toolkit.observe import RecordingObserver
from toolkit.synthetic.depth_sensor import SecondPerson

#: Standing person, 320 x 240 with Kinect-like noise at about 3 m: largest per-point error once
#: tracking (the ground truth is inside the body; the sensor sees its front surface).
STANDING_MAX_POINT_ERROR_M = 0.09
#: ... and the mean over the control points.
STANDING_MPJPE_M = 0.045
#: A short waving motion: mean error over the tracked frames.
MOTION_MPJPE_M = 0.05
#: After leaving and coming back, the mean error of the frames tracked again.
RECOVERED_MPJPE_M = 0.06
#: Seen points of a person cut by the image's lower border (the stature is then a default).
PARTIAL_MPJPE_M = 0.06
#: With a second person touching the user.
TOUCHING_MPJPE_M = 0.10


def _track(seq, **kw):
    tr = DepthTracker(seq.camera, True, background=seq.background, rng=0, **kw)
    return tr, [tr.process(d) for d in seq.depth]


def test_standing_pose_per_point_error(idle_sequence):
    seq = idle_sequence
    _, res = _track(seq)
    states = [r.state for r in res]
    assert states[0] == RECOVERING and states[-1] == TRACKING
    J = np.array([r.joints for r in res])
    err = np.linalg.norm(J - seq.joints13, axis=-1)
    tracked = np.array(states) == TRACKING
    assert err[tracked].max() < STANDING_MAX_POINT_ERROR_M
    assert err[tracked].mean() < STANDING_MPJPE_M
    assert all(r.observed.all() for r in res[3:])            # a standing person shows every point


def test_short_motion_error_and_constraints(wave_sequence):
    seq = wave_sequence
    tr, res = _track(seq)
    states = np.array([r.state for r in res])
    assert (states == TRACKING).mean() > 0.8
    J = np.array([r.joints for r in res])
    assert mpjpe(J[states == TRACKING], seq.joints13[states == TRACKING]) < MOTION_MPJPE_M
    # every output satisfies the hard constraints
    cfg = ConstraintConfig()
    for i, r in enumerate(res):
        prev = res[i - 1].joints_view if i and res[i - 1].state != LOST else None
        v = constraint_violations(r.joints_view, tr.dims, cfg, X_prev=prev, dt=1 / 30)
        assert v == {"length": 0, "collision": 0, "joint_limit": 0, "velocity": 0}, (i, v)
    # the segment lengths were refined towards this person's
    truth = BodyDimensions.from_stature(1.75)
    assert tr.dims.lengths.shape == truth.lengths.shape


def test_recovery_after_leaving_and_coming_back(idle_sequence):
    seq = idle_sequence
    empty = np.where(np.isfinite(seq.background), seq.background, np.nan).astype(np.float32)
    frames = list(seq.depth[:6]) + [empty] * 4 + list(seq.depth[6:])
    truth = list(seq.joints13[:6]) + [None] * 4 + list(seq.joints13[6:])
    tr = DepthTracker(seq.camera, True, background=seq.background, rng=0)
    res = [tr.process(d) for d in frames]
    states = [r.state for r in res]
    assert states[6:10] == [LOST] * 4 and all(r.reason == "no user" for r in res[6:10])
    assert all(np.isnan(r.joints).all() for r in res[6:10])
    assert states[10] == RECOVERING and res[10].reason == "init"
    assert states[-1] == TRACKING
    back = [i for i in range(10, len(res)) if states[i] != LOST]
    assert mpjpe(np.array([res[i].joints for i in back]), np.array([truth[i] for i in back])) < RECOVERED_MPJPE_M


@pytest.mark.parametrize("bad", ["nan", "zeros"])
def test_empty_depth_is_lost_not_a_crash(idle_sequence, bad):
    seq = idle_sequence
    d = np.full(seq.depth.shape[1:], np.nan if bad == "nan" else 0.0, np.float32)
    tr = DepthTracker(seq.camera, True, background=seq.background)
    r = tr.process(d)
    assert r.state == LOST and r.reason == "no depth" and np.isnan(r.joints).all()
    r = tr.process(seq.depth[0], mask=np.zeros(d.shape, bool))
    assert r.state == LOST and r.reason == "no user"


def test_input_checks(idle_sequence):
    seq = idle_sequence
    tr = DepthTracker(seq.camera, True)
    with pytest.raises(InputError, match="depth"):
        tr.process(seq.depth[0][:-1])
    with pytest.raises(InputError, match="background"):
        DepthTracker(seq.camera, True, background=np.zeros((3, 3), np.float32))
    with pytest.raises(InputError, match="output"):
        TrackerConfig(output="screen")
    mm = np.nan_to_num(seq.depth[0] * 1000).astype(np.uint16)   # uint16 millimetres are accepted
    r = DepthTracker(seq.camera, True, background=seq.background, rng=0).process(mm)
    assert r.state == RECOVERING


def test_partly_out_of_frame():
    """The camera sees the person from the hips up only: no crash, a skeleton for the visible part."""
    seq, _, _ = make_sequence("idle", 6, seed=8, target_height_m=1.6, distance_m=1.8, height_m=1.5)
    assert seq.visible13[:, -2:].sum() == 0                   # the feet are out of the image
    _, res = _track(seq)
    assert all(r.state != LOST for r in res)
    J = np.array([r.joints for r in res])
    seen = np.nonzero(seq.visible13.all(0))[0]                 # head, shoulders, elbows, hips
    assert len(seen) >= 7
    assert mpjpe(J[2:, seen], seq.joints13[2:, seen]) < PARTIAL_MPJPE_M
    assert not res[-1].observed[~seq.visible13.any(0)].any()  # the points out of the image were completed
    # completed hands still hang below their elbows, within reach
    X = res[-1].joints
    for e, h in ((3, 5), (4, 6)):
        assert X[h, 2] < X[e, 2] and np.linalg.norm(X[h] - X[e]) < 0.45


def _touches(seq) -> list:
    """Frames where the two people's pixels are 8-neighbours."""
    import cv2

    out = []
    for s in seq.subject:
        a = cv2.dilate((s == 1).astype(np.uint8), np.ones((3, 3), np.uint8)) > 0
        out.append(bool((a & (s == 2)).any()))
    return out


@pytest.mark.parametrize("from_start", [False, True])
def test_second_person_touching(from_start):
    """A second person comes to touch the user (or touches from the first frame): the user is still tracked."""
    together, _, _ = make_sequence("idle", 8, seed=9, second_person=SecondPerson(offset_m=(0.55, 0.0)))
    assert all(_touches(together))
    if from_start:
        seq = together
        frames, truth = seq.depth, seq.joints13
    else:
        alone, _, _ = make_sequence("idle", 8, seed=9)
        seq = alone
        frames = np.concatenate([alone.depth[:4], together.depth[4:]])
        truth = alone.joints13
    tr = DepthTracker(seq.camera, True, background=seq.background, rng=0)
    res = [tr.process(d) for d in frames]
    assert all(r.state != LOST for r in res)
    assert any(r.reason == "touching" for r in res[4:] if not from_start) or from_start
    J = np.array([r.joints for r in res])
    assert mpjpe(J[3:], truth[3:]) < TOUCHING_MPJPE_M


def test_camera_coordinates_without_a_pose(idle_sequence):
    seq = idle_sequence
    tr = DepthTracker(seq.camera, pose_known=False, background=seq.background, rng=0)
    res = [tr.process(d) for d in seq.depth[:6]]
    gt_cam = seq.camera.to_cam(seq.joints13[:6])
    J = np.array([r.joints for r in res])
    assert mpjpe(J[3:], gt_cam[3:]) < 0.08


def test_observer_receives_every_intermediate(idle_sequence):
    seq = idle_sequence
    obs = RecordingObserver()
    tr = DepthTracker(seq.camera, True, background=seq.background, rng=0, observer=obs)
    for d in seq.depth[:3]:
        tr.process(d)
    names = {d.get("name") for k, d in obs.reports if k in ("points3d", "rays", "lines3d", "joints3d")}
    assert {"depth/cloud", "depth/orus", "depth/spheres", "depth/curvature_centres", "depth/normals",
            "depth/radial_contour", "depth/skeleton", "depth/keypoints"} <= names
    assert len(obs.of_kind("depth_energy")) >= 3 and obs.of_kind("depth_radial")
    e = obs.of_kind("depth_energy")[0]
    assert {"surface", "centres", "contour", "previous", "length", "topology", "collision"} <= set(e["blocks"])
    assert any(d.get("name") == "depth/state" for d in obs.of_kind("scalar"))
