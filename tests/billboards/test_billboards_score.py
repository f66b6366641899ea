"""The position score (source 000 §3.1) on the perfectly aligned planar scene."""

from __future__ import annotations

import numpy as np
import pytest

from toolkit.billboards import PAIR_ANGLE_SIGMA, PositionScorer, ScoreConfig, evaluated_views, midway_camera, pair_weight
from toolkit.errors import InputError
from toolkit.skeleton import SKELETON_14

#: A perfectly aligned fan scores 1 up to bilinear resampling: texture noise and the one-pixel
#: alpha rim of the warped segments (about 1.5 % of a 60 x 170 px plank each).
ALIGNED_TOL = 0.04
#: Least drop of the score for a 2 cm displacement out of the plank's plane (the billboards tilt
#: away from the plank) and within it (they stay almost on it: only the small tilt of each
#: camera's plane about the bone remains).
DROP_2CM = {1: 0.1, 0: 0.01}

WRIST = SKELETON_14.index("l_wrist")
ELBOW = SKELETON_14.index("l_elbow")


@pytest.fixture(scope="module")
def scorer(planar_scene):
    return PositionScorer(planar_scene.images, planar_scene.labels, planar_scene.rig)


def test_aligned_scores_one(planar_scene, scorer):
    s = planar_scene
    ps = scorer.part_score(s.joints, s.part - 1)
    assert np.all(ps.n_billboards == len(s.rig))  # every billboard in every view
    assert np.all(np.abs(ps.per_view - 1) < ALIGNED_TOL)
    assert abs(scorer.joint_score(s.joints, WRIST) - 1) < ALIGNED_TOL
    # the elbow's other bone (upper arm) has no segment, so it adds nothing
    assert abs(scorer.joint_score(s.joints, ELBOW) - 1) < ALIGNED_TOL


@pytest.mark.parametrize("axis", [0, 1])
def test_score_drops_when_joint_moves(planar_scene, scorer, axis):
    s = planar_scene
    base = scorer.joint_score(s.joints, WRIST)
    prev = base
    for d in (0.01, 0.02, 0.04):
        J = s.joints.copy()
        J[WRIST, axis] += d
        sc = scorer.joint_score(J, WRIST)
        assert sc < prev
        if d == 0.02:
            assert sc < base - DROP_2CM[axis]
        prev = sc


def test_unscored_joint_is_nan(planar_scene, scorer):
    assert np.isnan(scorer.joint_score(planar_scene.joints, SKELETON_14.index("r_knee")))


def test_views_and_pair_weight(planar_scene):
    rig = planar_scene.rig
    views = evaluated_views(rig)
    assert len(views) == len(rig) + len(rig) * (len(rig) - 1) // 2
    assert [v.virtual for v in views] == [False] * len(rig) + [True] * 3
    mid = midway_camera(rig[0], rig[1])
    # on the arc between both cameras around the point they look at, aimed at that point
    from toolkit.cameras import closest_point_to_rays
    x = closest_point_to_rays(rig.centers[:2], np.array([rig[0].forward, rig[1].forward]))[0]
    d = [np.linalg.norm(c.center - x) for c in (rig[0], rig[1], mid)]
    assert d[2] == pytest.approx(0.5 * (d[0] + d[1]))
    to = [(c.center - x) / np.linalg.norm(c.center - x) for c in (rig[0], rig[1], mid)]
    assert np.arccos(to[2] @ to[0]) == pytest.approx(np.arccos(to[2] @ to[1]), abs=1e-9)
    assert mid.forward @ (x - mid.center) / d[2] == pytest.approx(1.0)
    a0 = np.arccos(np.clip(mid.forward @ rig[0].forward, -1, 1))
    a1 = np.arccos(np.clip(mid.forward @ rig[1].forward, -1, 1))
    assert abs(a0 - a1) < 1e-6
    # two cameras 100 degrees apart: the midway view still sees their common target in its image
    from toolkit.cameras import Camera
    A = Camera.look_at("a", [30.0, 0.0, 10.0], [0.0, 0.0, 1.0], fov_x_deg=8.0)
    B = Camera.look_at("b", [30.0 * np.cos(1.745), 30.0 * np.sin(1.745), 10.0], [0.0, 0.0, 1.0], fov_x_deg=8.0)
    m = midway_camera(A, B)
    assert m.in_image(m.project(np.array([0.0, 0.0, 1.0]))[None], margin=100)[0]
    assert pair_weight(0.0, PAIR_ANGLE_SIGMA) == 1.0
    assert np.isclose(pair_weight(PAIR_ANGLE_SIGMA, PAIR_ANGLE_SIGMA), np.exp(-0.5))


def test_colour_mismatch_lowers_score(planar_scene):
    s = planar_scene
    imgs = dict(s.images)
    name = s.rig[1].name
    imgs[name] = (255 - s.images[name]).astype(np.uint8)  # same geometry, other colours
    sc = PositionScorer(imgs, s.labels, s.rig).joint_score(s.joints, WRIST)
    assert sc < 0.9


def test_scorer_rejects_bad_input(planar_scene, scorer):
    s = planar_scene
    with pytest.raises(InputError, match="joints"):
        scorer.joint_score(s.joints[:3], WRIST)
    with pytest.raises(InputError, match="labels"):
        PositionScorer(s.images, {}, s.rig)
    with pytest.raises(InputError, match="sigma"):
        ScoreConfig(sigma=0.0)


def test_score_evaluation_is_fast(planar_scene, scorer):
    """One joint evaluation (3 cameras, 6 views) stays in the millisecond range (benchmarks measure 1280x720).

    CPU time of this process, not wall-clock time: other jobs on a shared machine must not fail it.
    """
    import time
    t0 = time.process_time()
    for _ in range(20):
        scorer.joint_score(planar_scene.joints, WRIST)
    assert (time.process_time() - t0) / 20 < 0.05


#: Principal-point errors of the measured cameras in the offsets test, pixels (measured
#: projection = true projection - error, so the images sit at measured projection + error).
CALIBRATION_ERROR_PX = np.array([[5.0, -4.0], [-3.0, 6.0], [2.0, 3.0]])
#: A score this far below the aligned one means the billboards are misaligned by several pixels.
MISALIGNED_DROP = 0.3
#: Least score lost by the ground truth against stage 1's joints under stage 1's offsets (the
#: offsets' gauge shifts the aligned pose by about a centimetre here).
GAUGE_DROP = 0.1


def test_stage1_offsets_realign_miscalibrated_cameras(planar_scene):
    """Stage 1's offsets, turned into cameras by ``corrected_rig``, realign the fan of stage 1's own joints.

    Stage 1 (``fit_offsets``) adds its offsets to the detected 2D joints; the cameras'
    principal points need the opposite shift.  With the wrong sign the billboards are
    misaligned by twice the calibration error and the search drifts.
    """
    from toolkit.cameras import Rig, camera_with_offset
    from toolkit.multiview import corrected_rig, fit_offsets

    s = planar_scene
    measured = []
    for cam, err in zip(s.rig, CALIBRATION_ERROR_PX):
        K = cam.K.copy()
        K[:2, 2] -= err
        measured.append(cam.replace(K=K))
    measured = Rig(tuple(measured))
    fit = fit_offsets(np.stack([c.project(s.joints) for c in s.rig]), measured)
    assert fit.success
    converted = PositionScorer(s.images, s.labels, corrected_rig(measured, fit.offsets))
    raw = PositionScorer(s.images, s.labels, corrected_rig(measured, -fit.offsets))
    aligned = converted.joint_score(fit.joints3d, WRIST)
    assert abs(aligned - 1) < ALIGNED_TOL
    assert raw.joint_score(fit.joints3d, WRIST) < aligned - MISALIGNED_DROP
    # the offsets' gauge: stage 1's offsets align stage 1's joints (shifted a little from the
    # truth), so the score prefers them to the ground truth; the true errors align the truth
    assert converted.joint_score(s.joints, WRIST) < aligned - GAUGE_DROP
    truth = PositionScorer(s.images, s.labels,
                           Rig(tuple(camera_with_offset(c, e) for c, e in zip(measured, CALIBRATION_ERROR_PX))))
    assert abs(truth.joint_score(s.joints, WRIST) - 1) < ALIGNED_TOL
