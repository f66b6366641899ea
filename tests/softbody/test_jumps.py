"""A limb that jumps between two frames is fitted again held, and a jump the fit keeps is not trusted
(:func:`toolkit.softbody.confidence.largest_step`, ``TrackConfig.hold_step``, ``ConfidenceConfig.lost_step``)."""

import numpy as np
import pytest

from toolkit.skeleton import SKELETON_14
from toolkit.softbody.confidence import ConfidenceConfig, body_frame_joints, frame_confidence, largest_step
from toolkit.softbody.model import DOF_NAMES
from toolkit.softbody.track import TrackConfig, _held_if_jumped, part_support, track_frame

from tests.softbody.conftest import model_walk

#: The forearm swung this far about the shoulder's own axis (radians): the wrist moves about 0.4 m.
SWING_RAD = 2.0
#: A held fit's wrist must stay this close to the previous frame's (metres): the walk moves it about
#: 2 cm per frame, the fit's noise a few more.
HELD_M = 0.08
L_WRIST = SKELETON_14.index("l_wrist")


@pytest.fixture(scope="module")
def walk():
    model, truth, joints, clouds, _, _ = model_walk(4, 400, seed=5)
    return model, truth, joints, clouds


def _swung(params):
    x = params.pose.copy()
    x[DOF_NAMES.index("l_shoulder_rotation")] += SWING_RAD
    x[DOF_NAMES.index("l_elbow")] = 1.6   # bent: the turn about the upper arm sweeps the forearm round
    return params.replace(pose=x)


def test_body_frame_is_the_pelvis_frame(walk):
    model, truth, joints, _ = walk
    b = body_frame_joints(joints[0])
    assert np.allclose(b[SKELETON_14.index("l_hip"), 1:], 0.0, atol=1e-9)
    assert b[SKELETON_14.index("l_hip"), 0] > 0 > b[SKELETON_14.index("r_hip"), 0]
    assert b[SKELETON_14.index("neck"), 2] > 0.3 and abs(b[SKELETON_14.index("neck"), 0]) < 1e-9
    # the same move seen from anywhere: a turned and shifted world gives the same frame
    c, s = np.cos(0.7), np.sin(0.7)
    R = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    assert np.allclose(body_frame_joints(joints[0] @ R.T + [1.0, 2.0, 0.0]), b, atol=1e-9)


def test_confidence_says_a_limb_that_jumped(walk):
    model, truth, joints, clouds = walk
    cfg = ConfidenceConfig()
    walked = frame_confidence(model, truth[1], clouds[1], previous=joints[0])
    jumped = frame_confidence(model, _swung(truth[1]), clouds[1], previous=joints[0])
    unmeasured = frame_confidence(model, _swung(truth[1]), clouds[1])
    assert walked.verdict == "trusted" and walked.step < 0.1   # a walk: a few centimetres per frame
    assert largest_step(model.joints(_swung(truth[1])), joints[0]) > cfg.lost_step
    assert jumped.verdict == "lost" and jumped.step > cfg.lost_step
    assert np.isnan(unmeasured.step)   # no previous frame: not measured
    # over several frames the same move is a slower one
    assert frame_confidence(model, _swung(truth[1]), clouds[1], previous=joints[0], frames_since=3).step \
        == pytest.approx(jumped.step / 3)


def test_a_limb_that_jumped_is_fitted_again_held(walk):
    model, truth, joints, clouds = walk
    cfg = TrackConfig()
    # the left forearm's points gone (no texture): a fit started with it swung round keeps it there
    near = part_support(model, truth[1], clouds[1], 0.06)
    assert near[4] > 0
    from toolkit.softbody.distance import primitive_distances

    e = primitive_distances(model.state(truth[1]), clouds[1])
    cloud = clouds[1][model.prim_frame[np.argmin(e, axis=1)] != 4]
    f = track_frame(model, _swung(truth[1]), cloud, cfg, anchor=_swung(truth[1]))
    assert np.linalg.norm(model.joints(f.params)[L_WRIST] - joints[1][L_WRIST]) > 0.2
    g, held = _held_if_jumped(model, f, truth[0], truth[0], cloud, cfg, anchor=truth[0])
    assert held
    assert np.linalg.norm(model.joints(g.params)[L_WRIST] - joints[1][L_WRIST]) < HELD_M
    # a fit that did not jump is kept as it is
    same, again = _held_if_jumped(model, g, truth[0], truth[0], cloud, cfg, anchor=truth[0])
    assert not again and same is g
    # switched off
    kept, off = _held_if_jumped(model, f, truth[0], truth[0], cloud, TrackConfig(hold_step=0.0), anchor=truth[0])
    assert not off and kept is f
