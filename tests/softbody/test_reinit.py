"""Joints triangulated from detections in two views, with a view's limb labels swapped
(:func:`toolkit.softbody.reinit.triangulate_views`)."""

import numpy as np
import pytest

from toolkit.cameras import Camera
from toolkit.errors import InputError
from toolkit.softbody.mesh import sample_surface
from toolkit.softbody.reinit import _SWAPS, triangulate_views

from tests.softbody.conftest import model_walk

#: Keypoint noise of the detections, pixels, and what it leaves in the joints at 3.5 m (about 1 cm per
#: pixel in these 320-pixel-wide views, two views 90 degrees apart).
NOISE_PX = 2.0
NOISY_MM = 40.0


@pytest.fixture(scope="module")
def views():
    model, truth, joints, _, _, _ = model_walk(4, 10, seed=1)
    t = 3
    centre = joints[t, 1] * [1, 1, 0] + [0, 0, 1.0]
    cams = [Camera.look_at(f"c{i}", centre + 3.5 * np.array([np.cos(a), np.sin(a), 0.0]), centre,
                           size=(320, 240), fov_x_deg=60) for i, a in enumerate(np.radians([-90, 0]))]
    cloud = sample_surface(model, truth[t], 2000, np.random.default_rng(0))
    return joints[t], cams, cloud, joints[t - 2]   # the last frame trusted: two frames (80 ms) before


def _mm(a, b):
    return 1000 * float(np.linalg.norm(a - b, axis=-1).mean())


def test_swapped_labels_in_one_view_are_undone(views):
    joints, cams, cloud, before = views
    rng = np.random.default_rng(4)
    pts = np.stack([c.project(joints) for c in cams]) + rng.normal(0, NOISE_PX, (2, 14, 2))
    conf = np.ones((2, 14))
    for swap in (("arms",), ("legs",), ("arms", "legs")):
        seen = pts.copy()
        seen[1] = seen[1][_SWAPS[swap]]          # the second view's limbs labelled the wrong way round
        found = triangulate_views(seen, conf, cams, cloud=cloud, previous=before)
        assert found.complete and _mm(found.joints, joints) < NOISY_MM, swap
        assert set(found.swapped[1]) ^ set(found.swapped[0]) == set(swap)
    # every view mirrored alike: the same points; the previous pose tells the labels
    mirrored = np.stack([p[_SWAPS[("arms", "legs")]] for p in pts])
    found = triangulate_views(mirrored, conf, cams, cloud=cloud, previous=before)
    assert _mm(found.joints, joints) < NOISY_MM


def test_keypoints_the_views_do_not_agree_on_are_dropped(views):
    joints, cams, cloud, before = views
    pts = np.stack([c.project(joints) for c in cams])
    conf = np.ones((2, 14))
    pts[0, 4] += [0.0, 60.0]                      # a wrist 60 px off in one view, across the epipolar lines
    conf[1, 0] = 0.1                              # a head the detector hardly saw
    found = triangulate_views(pts, conf, cams, cloud=cloud, previous=before)
    assert not found and np.isnan(found.joints[[0, 4]]).all()
    ok = np.isfinite(found.joints).all(axis=1)
    assert _mm(found.joints[ok], joints[ok]) < 1.0


def test_bad_shapes_are_refused(views):
    _, cams, _, _ = views
    with pytest.raises(InputError, match="points2d"):
        triangulate_views(np.zeros((2, 13, 2)), np.ones((2, 13)), cams)
    with pytest.raises(InputError, match="cameras"):
        triangulate_views(np.zeros((1, 14, 2)), np.ones((1, 14)), cams[:1])
