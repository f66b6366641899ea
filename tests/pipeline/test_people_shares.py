"""Each person's share of the foreground by depth among everyone's posed templates (toolkit/pipeline/people.py).

Two rendered bodies cross in front of a camera, one partly hiding the other: the share that
stages 2-4 take for each person holds its own visible pixels and not the other's.  Split by where
the people stand (:func:`toolkit.silhouettes.people.split_masks`, what stage 1 uses), each one's
box takes pixels of the other (0.88 of its own, 0.11 of the other's).  The silhouette stage of
several people (:func:`toolkit.pipeline.people.estimate_people_silhouettes`) hands on these shares.
"""

from __future__ import annotations

import numpy as np
import pytest

from toolkit.anthropometry.proportions import BodyProportions
from toolkit.body.model import BodyModel
from toolkit.cameras import Camera, Rig
from toolkit.motion import generate_motion
from toolkit.pipeline.people import depth_ordered_shares
from toolkit.silhouettes.people import split_masks
from toolkit.synthetic.render import Raycaster
from toolkit.template import Template

SIZE = (320, 240)
#: Share of a person's visible pixels its own share must hold.
OWN_SHARE = 0.9
#: Share of a person's visible pixels another person's share may hold (the template is a generic body:
#: its outline is a pixel or two off the true one's).
STOLEN_SHARE = 0.08


def _rig():
    cams = [Camera.look_at("front", [0.0, -5.0, 1.5], [0, 0, 0.9], size=SIZE, focal_px=260.0),
            Camera.look_at("side", [5.0, 0.0, 1.5], [0, 0, 0.9], size=SIZE, focal_px=260.0)]
    return Rig(tuple(cams))


@pytest.fixture(scope="module")
def crossing():
    """Two walkers, the second 1 m behind the first and 0.3 m aside in the front camera."""
    rng = np.random.default_rng(5)
    rig = _rig()
    meshes, joints, ground = [], [], []
    for k, xy in enumerate(([0.0, 0.0], [0.3, 1.0])):
        props = BodyProportions.sample(1.72 + 0.05 * k, rng)
        J = generate_motion("walk", props, 1, 25.0, rng)[0]
        J = J - np.r_[(J[8, :2] + J[11, :2]) / 2, 0.0] + np.r_[xy, 0.0]
        meshes.append(BodyModel.sample(props, rng, detail=0.4).mesh(J))
        joints.append(J)
        ground.append((J[8, :2] + J[11, :2]) / 2)
    caster = Raycaster()
    ids = [caster.cast(cam, meshes)[1] for cam in rig]  # subject ids per camera (0: none)
    return rig, joints, np.array(ground), ids


def _held(shares, ids, v):
    """held[k, j]: share of person j's visible pixels in camera v that person k's share holds."""
    out = np.zeros((2, 2))
    for k in range(2):
        for j in range(2):
            true = ids[v] == j + 1
            out[k, j] = np.sum(shares[k][v] & true) / max(true.sum(), 1)
    return out


def test_each_person_keeps_its_own_pixels_where_they_cross(crossing):
    rig, joints, ground, ids = crossing
    fg = [i > 0 for i in ids]
    # the front camera sees the person behind partly hidden, the side camera sees both apart
    assert 0 < np.sum(ids[0] == 2) < 0.8 * np.sum(ids[1] == 2)
    split, _ = split_masks(fg, rig, ground)
    shares = depth_ordered_shares(split, joints, [rig, rig], Template())
    for v in range(len(rig)):
        assert not np.any(shares[0][v] & shares[1][v])  # exclusive
        assert np.array_equal(shares[0][v] | shares[1][v], fg[v] & (split[0][v] | split[1][v]))
        held = _held(shares, ids, v)
        assert held[0, 0] >= OWN_SHARE and held[1, 1] >= OWN_SHARE, (v, held)
        assert held[0, 1] <= STOLEN_SHARE and held[1, 0] <= STOLEN_SHARE, (v, held)
    # split by where they stand alone, each takes pixels of the other (0.88 own, 0.11 of the other's)
    before = _held(split, ids, 0)
    assert min(before[0, 0], before[1, 1]) < OWN_SHARE and max(before[0, 1], before[1, 0]) > STOLEN_SHARE, before


def test_a_person_without_a_pose_keeps_what_no_template_reaches(crossing):
    rig, joints, ground, ids = crossing
    fg = [i > 0 for i in ids]
    split, _ = split_masks(fg, rig, ground)
    shares = depth_ordered_shares(split, [joints[0], np.full((14, 3), np.nan)], [rig, rig], Template())
    held = _held(shares, ids, 1)  # the side camera: the two apart
    assert held[0, 0] >= OWN_SHARE and held[1, 1] >= OWN_SHARE, held
    # one person, or a camera without a frame, is left as it is
    assert depth_ordered_shares([split[0]], [joints[0]], [rig], Template()) == [split[0]]
    none = depth_ordered_shares([[None, split[0][1]], [None, split[1][1]]], joints, [rig, rig], Template())
    assert none[0][0] is None and none[1][0] is None


class _Frames:
    """The least of a dataset :func:`estimate_people_silhouettes` reads: frames (the subject ids drawn
    grey on black) and their count."""

    def __init__(self, rig, ids):
        self.rig, self.ids, self.n_frames, self.fps = rig, ids, len(ids), 25.0

    def frame(self, camera, t):
        return np.repeat((self.ids[t][self.rig.names.index(camera)] > 0)[..., None] * np.uint8(200), 3, -1)


class _Foreground:
    """A foreground extractor of :class:`_Frames`' images."""

    def extract(self, image):
        from types import SimpleNamespace

        return SimpleNamespace(mask=image[..., 0] > 0)


def test_stages_2_to_4_take_the_depth_ordered_shares(crossing):
    from toolkit.multiview import corrected_rig
    from toolkit.pipeline.people import estimate_people_silhouettes
    from toolkit.silhouettes import BuildConfig, build_database

    rig, joints, ground, ids = crossing
    db = build_database(BuildConfig(motions=("walk",), sequences_per_motion=2, frames_per_sequence=40,
                                    frame_stride=2, views_per_pose=12), 11)
    dataset = _Frames(rig, [ids, ids])
    positions = np.repeat(ground[:, None], 2, 1)
    frames = list(estimate_people_silhouettes(dataset, db, rig, (positions, np.ones((2, 2), bool)),
                                              extractors={c: _Foreground() for c in rig.names}))
    assert len(frames) == 2
    for pf in frames:
        split, _ = split_masks([i > 0 for i in ids], rig, ground)
        J = [e.joints3d if e.ok else np.full((14, 3), np.nan) for e in pf.estimates]
        want = depth_ordered_shares(split, J, [corrected_rig(rig, e.offsets) for e in pf.estimates], Template())
        for k in range(2):
            for v in range(len(rig)):
                assert np.array_equal(pf.masks[k][v], want[k][v]), (k, v)
        assert not np.any(pf.masks[0][0] & pf.masks[1][0])
    # where the two cross the shares are not where they stand alone
    assert any(not np.array_equal(pf.masks[k][0], split[k][0]) for k in range(2))
