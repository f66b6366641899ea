"""A limb held in the wrong place while the true one sticks out of the outline is said to be lost
(``ConfidenceConfig.lost_missed_outline``), though the points fit: the arms of a jump, a run's forearm."""

import numpy as np
import pytest

from toolkit.cameras import Camera
from toolkit.softbody.confidence import ConfidenceConfig, frame_confidence
from toolkit.softbody.distance import primitive_distances
from toolkit.softbody.model import DOF_NAMES
from toolkit.softbody.silhouette import model_mask, silhouette_views

from tests.softbody.conftest import model_walk

#: Left and right upper arms and forearms (frames of toolkit.softbody.model.FRAMES).
ARM_FRAMES = (3, 4, 5, 6)
#: The true left arm: swung forwards and bent (radians), as in a run.
FLEXION, ELBOW = 0.9, 1.6


@pytest.fixture(scope="module")
def swung():
    """A walker with the left arm swung forwards and bent (the truth, its mask in a camera looking at its
    side) and its points without the arms' (skin without texture); the fit holds the arm down by the body,
    inside the outline in that view."""
    model, truth, joints, _, _, _ = model_walk(1, 600, seed=11)
    x = truth[0].pose.copy()
    x[DOF_NAMES.index("l_shoulder_flexion")] = FLEXION
    x[DOF_NAMES.index("l_elbow")] = ELBOW
    up = truth[0].replace(pose=x)
    from toolkit.softbody.mesh import surface_mesh

    v, _ = surface_mesh(model, up, voxel=0.02)
    points = v[np.random.default_rng(11).choice(len(v), min(800, len(v)), replace=False)]
    e = primitive_distances(model.state(up), points)
    points = points[~np.isin(model.prim_frame[np.argmin(e, axis=1)], ARM_FRAMES)]
    centre = joints[0, 1] * [1, 1, 0] + [0, 0, 1.0]
    side = joints[0, 2] - joints[0, 5]   # left shoulder - right shoulder: the camera looks along it
    side = side * [1, 1, 0] / np.linalg.norm(side * [1, 1, 0])
    cams = [Camera.look_at("side", centre + 3.5 * side, centre, size=(160, 120), fov_x_deg=60)]
    sil = silhouette_views(cams, [model_mask(model, up, c) for c in cams])
    return model, up, truth[0], points, sil


def test_an_arm_held_down_under_a_swung_arm_is_lost(swung):
    model, up, down, points, sil = swung
    cfg = ConfidenceConfig()
    right = frame_confidence(model, up, points, silhouettes=sil)
    wrong = frame_confidence(model, down, points, silhouettes=sil)
    assert right.verdict == "trusted" and right.missed_outline < 0.01
    assert wrong.missed_outline > cfg.lost_missed_outline and wrong.verdict == "lost"
    # the points alone do not tell (the arms have none), nor do the other silhouette shares (the arm held
    # down lies in the mask): without the missed outline the frame would be trusted
    assert wrong.residual >= cfg.trusted_residual and wrong.silhouette >= cfg.trusted_silhouette
    assert wrong.coverage >= cfg.lost_coverage
    # another body where the swung arm is (a second person touching the subject, standing there: a piece
    # as long as a person): their outline is no miss
    arm = np.linspace(model.joints(up)[3], model.joints(up)[4], 20)   # the left forearm, taken for another body's
    person = np.linspace(arm[-1] * [1, 1, 0], arm[-1] * [1, 1, 0] + [0, 0, 1.7], 60)
    other = frame_confidence(model, down, points, silhouettes=sil, others=np.vstack([arm, person]))
    assert other.missed_outline < cfg.lost_missed_outline and other.verdict == "trusted"
    # the arm's points alone, a piece shorter than a person, are the subject's limb the model left: missed
    alone = frame_confidence(model, down, points, silhouettes=sil, others=arm)
    assert alone.missed_outline > cfg.lost_missed_outline and alone.verdict == "lost"
    # switched off
    off = frame_confidence(model, down, points, silhouettes=sil, config=ConfidenceConfig(lost_missed_outline=0.99))
    assert off.verdict == "trusted" and off.missed_outline == pytest.approx(wrong.missed_outline)
    # no masks: not measured
    assert np.isnan(frame_confidence(model, down, points).missed_outline)
