"""Seam correction (source 000 §3.3) on a toy segmentation and on a ray-cast body."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from toolkit.anthropometry import BodyProportions
from toolkit.billboards import SEAM_DEPTH_M, build_billboards, detect_seams, membership_of, render_view
from toolkit.cameras import Camera, Rig
from toolkit.errors import InputError
from toolkit.observe import RecordingObserver
from toolkit.synthetic import BodyModel, BodyShape, Raycaster

#: Seams must remove most cracks: at most this fraction of them may remain.
CRACKS_LEFT = 0.2


def test_toy_seams_follow_depth():
    lab = np.zeros((6, 8), np.uint8)
    lab[1:5, 1:4] = 1
    lab[1:5, 4:7] = 2
    depth = np.full(lab.shape, 5.0)
    sm = detect_seams(lab, depth)
    assert sm.mask[1:5, 3].all() and sm.mask[1:5, 4].all() and sm.count == 8
    assert np.all(sm.membership[1:5, 3] == (1 << 1) | (1 << 2))
    assert np.all(sm.membership[2, 1] == 1 << 1)
    depth[:, 4:] = 5.0 + 2 * SEAM_DEPTH_M  # part 2 lies behind: an occlusion boundary, not a seam
    assert detect_seams(lab, depth).count == 0
    subject = np.where(lab == 2, 2, 1)  # another subject: no seam either
    assert detect_seams(lab, np.full(lab.shape, 5.0), subject=subject).count == 0
    assert np.array_equal(membership_of(lab), np.where(lab > 0, 1 << lab.astype(np.uint16), 0))


def test_seams_reject_bad_input():
    with pytest.raises(InputError, match="depth"):
        detect_seams(np.zeros((4, 4), np.uint8), np.zeros((3, 4)))
    with pytest.raises(InputError, match="labels"):
        detect_seams(np.zeros((4, 4), float), np.zeros((4, 4)))


@pytest.fixture(scope="module")
def body_views():
    prop = BodyProportions.from_height(1.75)
    J = prop.rest_pose()
    mesh = BodyModel(BodyShape(prop), rng=0).mesh(J)
    a = Camera.look_at("A", [0.5, 4.0, 1.2], [0, 0, 0.95], size=(320, 360), fov_x_deg=30)
    b = Camera.look_at("B", [-2.0, 3.5, 1.5], [0, 0, 0.95], size=(320, 360), fov_x_deg=30)
    rc = Raycaster()
    lab_a, _, depth_a = rc.cast(a, [mesh])
    lab_b, _, _ = rc.cast(b, [mesh])
    return J, a, b, lab_a, depth_a, lab_b


def _cracks(cov: np.ndarray) -> int:
    """Uncovered pixels with covered pixels within 2 px on both sides (horizontally or vertically)."""
    c = cov.astype(np.uint8)
    k = np.ones((1, 5), np.uint8)
    closed = cv2.morphologyEx(c, cv2.MORPH_CLOSE, k).astype(bool) | cv2.morphologyEx(c, cv2.MORPH_CLOSE, k.T).astype(bool)
    return int((closed & ~cov).sum())


def test_seams_close_cracks_on_a_body(body_views):
    J, a, b, lab_a, depth_a, lab_b = body_views
    obs = RecordingObserver()
    sm = detect_seams(lab_a, depth_a, camera="A", observer=obs)
    assert sm.count > 100
    assert obs.of_kind("mask")[0]["mask"] is sm.mask
    # every seam pixel has a differently labelled 4-neighbour within φ
    ys, xs = np.nonzero(sm.mask)
    for y, x in zip(ys[:200], xs[:200]):
        ok = False
        for dy, dx in ((0, 1), (0, -1), (1, 0), (-1, 0)):
            l2, d2 = lab_a[y + dy, x + dx], depth_a[y + dy, x + dx]
            ok |= bool(l2 > 0 and l2 != lab_a[y, x] and abs(d2 - depth_a[y, x]) < SEAM_DEPTH_M)
        assert ok
    img = np.full(lab_a.shape + (3,), 200, np.uint8)
    rig = Rig((a,))
    covers = []
    for seams in (None, {"A": sm}):
        _, alpha, _ = render_view(build_billboards({"A": img}, {"A": lab_a}, J, rig, seams=seams), b)
        covers.append(alpha >= 0.5)
    without, with_ = _cracks(covers[0]), _cracks(covers[1])
    assert without > 100  # cracks appear between fans without seam correction
    assert with_ <= CRACKS_LEFT * without
