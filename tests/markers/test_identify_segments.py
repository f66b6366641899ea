"""Identification of a segment's markers as a whole (issue 17: swaps inside one segment)."""

from __future__ import annotations

import numpy as np

from toolkit.anthropometry import BodyProportions
from toolkit.markers import get_marker_set
from toolkit.markers.identify import IdentifyConfig, fit_template, register_segment
from toolkit.markers.label import TEMPLATE_STATURE_M
from toolkit.motion import synthesize_motion
from toolkit.skeleton import JOINTS_14


def _rot(axis, deg):
    axis = np.asarray(axis, float) / np.linalg.norm(axis)
    K = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    a = np.radians(deg)
    return np.eye(3) + np.sin(a) * K + (1 - np.cos(a)) * K @ K


def test_a_shank_plate_higher_than_the_template_keeps_its_labels():
    """The benchmark's walk/cluster/101 in small: a tall walker's left shank plate 6 cm above the template's.

    Pairing the template's plate with the nearest points gave its two
    proximal markers (LSK3, LSK4) the points of the two distal ones and left
    those unlabelled (the fitted plate one marker spacing too low); the
    segment registered as a whole finds the plate where it is.
    """
    ms = get_marker_set("cluster")
    labels = ms.labels
    joints = synthesize_motion("walk", BodyProportions.from_height(1.88), 40, 100.0, rng=4).joints[5]
    X = ms.positions(joints)
    up = joints[JOINTS_14.index("l_knee")] - joints[JOINTS_14.index("l_ankle")]
    plate = [labels.index(f"LSK{i}") for i in range(1, 5)]
    X[plate] += 0.06 * up / np.linalg.norm(up)
    rng = np.random.default_rng(8)
    X += rng.normal(0, 0.001, X.shape)
    ghosts = X[plate].mean(axis=0) + rng.normal(0, 0.15, (2, 3))  # two spurious points near the plate
    points = np.concatenate([X, ghosts])
    order = rng.permutation(len(points))
    template_joints = BodyProportions.from_height(TEMPLATE_STATURE_M).rest_pose()
    ident = fit_template(points[order], ms.positions(template_joints), template_joints, ms.segments)
    truth = np.argsort(order)[:ms.n_markers]
    wrong = [labels[i] for i in np.flatnonzero(ident.point_of_marker != truth)]
    assert wrong == [], wrong


PLATE = np.array([[0.040, 0.030, 0.0], [0.042, -0.031, 0.0], [-0.041, 0.029, 0.0], [-0.040, -0.030, 0.0]])


def test_a_nearly_symmetric_plate_is_not_turned_over():
    """Four plate markers at the corners of a near rectangle: the plate turned over about either axis,
    or about its normal, fits within the noise; the pairing turning it least wins."""
    plain = IdentifyConfig(segment_slack_m=0.0)  # the best rigid fit alone
    wrong = {"default": 0, "plain": 0}
    rng = np.random.default_rng(2)
    for trial in range(20):
        R = _rot(rng.normal(size=3), rng.uniform(5, 40))  # the real plate turned from the template ...
        t = rng.normal(0, 0.03, 3)  # ... and moved
        template = PLATE @ _rot(rng.normal(size=3), rng.uniform(0, 180)).T + [0.3, 0.1, 0.9]
        real = (template - template.mean(0)) @ R.T + template.mean(0) + t + rng.normal(0, 0.0015, (4, 3))
        points = np.concatenate([real, template.mean(0) + rng.normal(0, 0.12, (2, 3))])  # + 2 ghosts
        for name, cfg in (("default", IdentifyConfig()), ("plain", plain)):
            moved = register_segment(template, points, cfg)
            wrong[name] += bool(np.linalg.norm(moved - real, axis=1).max() > 0.006)
    assert wrong["default"] == 0, wrong
    assert wrong["plain"] >= 2, wrong  # the plate is symmetric enough to be turned over by the fit alone


def test_a_plate_with_a_marker_missing_is_placed_from_the_other_three():
    cfg = IdentifyConfig()
    template = PLATE @ _rot([1, 0.2, 0], 70).T + [0.0, 0.4, 0.5]
    real = (template - template.mean(0)) @ _rot([0, 0, 1], 25).T + template.mean(0) + [0.0, 0.0, 0.07]
    points = np.concatenate([real[[0, 2, 3]], [[0.5, 0.5, 0.5]]])  # marker 1 not seen, a ghost far off
    moved = register_segment(template, points, cfg)
    assert np.linalg.norm(moved - real, axis=1).max() < 1e-6
    assert register_segment(template, points[:2], cfg) is None  # fewer than three points: no rigid placement
