"""The subject's points told from other bodies' (toolkit/softbody/separate.py): noiseless points of the model
itself, a second copy of it beside it, the floor, a hand that moved, clutter."""

import numpy as np
import pytest

from toolkit.anthropometry import BodyProportions
from toolkit.softbody import SoftBodyModel, distance
from toolkit.softbody.mesh import sample_surface
from toolkit.softbody.model import DOF_NAMES
from toolkit.softbody.separate import link_distance, separate_subject

NEAR, GATE = 0.03, 0.25


@pytest.fixture(scope="module")
def body():
    model = SoftBodyModel(BodyProportions.from_height(1.75))
    params = model.default_params(root_translation=(0.0, 0.0, 0.95))
    return model, params, sample_surface(model, params, 800, np.random.default_rng(0))


def _split(model, params, pts, **kw):
    return separate_subject(model, params, pts, near=NEAR, gate=GATE, link=link_distance(pts, 0.04), **kw)


def test_a_second_person_touching_and_the_floor_are_left_out(body):
    model, params, own = body
    for dx in (0.45, -0.45):
        other = own + np.array([dx, 0.0, 0.0])          # arms touching the subject's
        xy = np.random.default_rng(1).uniform(-1.0, 1.0, (1500, 2))
        floor = np.c_[xy, np.zeros(len(xy))]
        pts = np.vstack([own, other, floor])
        sep = _split(model, params, pts)
        n = len(own)
        assert sep.keep[:n].mean() > 0.99
        assert sep.keep[n:2 * n].mean() < 0.1           # the copy's contact band, within the near margin
        assert sep.keep[2 * n:].mean() < 0.03           # the floor under the feet
        assert (sep.keep ^ sep.other ^ sep.stray).all() and not (sep.keep & sep.other).any()
        # the copy's arm touches the subject's all along (contact within a link, here 0.1 m: a sparse cloud)
        assert 0.05 < _split(model, params, np.vstack([own, other])).contact < sep.contact


def test_a_hand_that_moved_is_kept_a_blob_apart_is_stray(body):
    model, params, _ = body
    k = DOF_NAMES.index("l_shoulder_flexion")
    pose = params.pose.copy()
    pose[k] = 0.25                                      # the hand 15 cm forward of the prediction
    moved = sample_surface(model, params.replace(pose=pose), 800, np.random.default_rng(2))
    blob = np.array([0.0, -0.3, 1.3]) + np.random.default_rng(3).normal(0, 0.01, (20, 3))  # 0.15 m in front
    sep = _split(model, params, np.vstack([moved, blob]))
    assert sep.keep[:800].all()                         # the moved hand is continuous with its arm
    assert sep.stray[800:].all()                        # touches neither the subject nor another body
    assert sep.undecided > 0
    # with a reach of a still body (3 cm beyond the near margin) the moved hand is another body's
    tight = _split(model, params, moved, reach=0.03)
    assert not tight.keep.all() and tight.other.any()


def test_the_last_frame_s_other_bodies_are_remembered(body):
    """A second person's side 0.25 m away, all of it within the gate and touching the subject:
    taken for the subject's; seen as another body in the last frame, it stays one."""
    model, params, own = body
    other = own + np.array([0.25, 0.0, 0.0])
    other = other[distance(model, params, other) < 0.8 * GATE]
    pts = np.vstack([own, other])
    blind = _split(model, params, pts)
    seen = _split(model, params, pts, others=other + 0.01)
    n = len(own)
    assert blind.keep[n:].mean() > 0.2
    assert seen.keep[n:].mean() < blind.keep[n:].mean() / 2
    assert seen.keep[:n].mean() > 0.97


def test_empty_and_far_clouds(body):
    model, params, own = body
    sep = _split(model, params, np.zeros((0, 3)))
    assert sep.keep.shape == (0,) and sep.contact == 0.0
    far = _split(model, params, own + np.array([3.0, 0.0, 0.0]))
    assert not far.keep.any() and far.other.all()
