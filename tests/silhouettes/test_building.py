"""Rendering a silhouette database: views, entries, mirror images, flow, determinism, the cache."""

from __future__ import annotations

import numpy as np
import pytest

from toolkit.anthropometry.proportions import BodyProportions
from toolkit.errors import InputError
from toolkit.motion import generate_motion
from toolkit.silhouettes import (
    BuildConfig,
    SilhouetteDatabase,
    build_database,
    default_database,
    descriptor_grid,
    render_silhouettes,
    view_around,
)
from toolkit.silhouettes.building import CACHE_ENV, subject_frame
from toolkit.skeleton import SKELETON_14
from toolkit.body.model import BodyModel

TINY = BuildConfig(motions=("walk", "kick"), sequences_per_motion=1, frames_per_sequence=10, frame_stride=5,
                   views_per_pose=4)
#: Normalised joints of a full-body silhouette lie in the box up to the body's volume beyond
#: the joint centres (a wrist or ankle is never more than this fraction outside).
BOX_SLACK = 0.05
J = SKELETON_14.index


def standing():
    props = BodyProportions.from_height(1.75)
    return props, props.rest_pose()


def test_subject_frame_of_the_rest_pose():
    _, pose = standing()  # faces +y, left side at -x
    facing, left = subject_frame(pose)
    np.testing.assert_allclose(facing, [0, 1, 0], atol=1e-9)
    np.testing.assert_allclose(left, [-1, 0, 0], atol=1e-9)


@pytest.mark.parametrize("azimuth, left_on_image_right", [(0.0, True), (180.0, False)])
def test_view_around_front_and_back(azimuth, left_on_image_right):
    _, pose = standing()
    view = view_around(pose, azimuth, 10.0, 20.0, subject_height_px=120.0)
    uv = view.project(pose)
    w, h = view.size
    assert np.all((uv >= 0) & (uv <= [w - 1, h - 1]))
    assert (uv[J("l_shoulder"), 0] > uv[J("r_shoulder"), 0]) == left_on_image_right
    stature_px = uv[J("l_ankle"), 1] - uv[J("head"), 1]
    assert 0.8 * 120 < stature_px < 120  # the head joint is below the top of the head


def test_rendered_silhouettes_fit_their_windows():
    props, pose = standing()
    model = BodyModel.sample(props, 0, detail=0.3)
    mesh = model.mesh(pose)
    views = [view_around(pose, a, e, d) for a, e, d in ((0, 0, 5), (90, 20, 20), (200, 35, 40))]
    masks, flows = render_silhouettes(mesh.vertices, mesh.triangles, views)
    for view, m in zip(views, masks):
        assert m.shape == view.size[::-1]
        assert m.any() and not m[0].any() and not m[-1].any() and not m[:, 0].any() and not m[:, -1].any()
    assert flows == [None] * 3


def test_flow_of_a_sideways_shift():
    props, pose = standing()
    mesh = BodyModel.sample(props, 0, detail=0.3).mesh(pose)
    view = view_around(pose, 0.0, 0.0, 10.0)
    shift_m = 0.05
    prev = mesh.vertices - shift_m * view.R[0]  # the body moved by 5 cm along the camera's x axis
    (mask,), (flow,) = render_silhouettes(mesh.vertices, mesh.triangles, [view], prev)
    f = view.K[0, 0]
    depth = (mesh.vertices - view.center) @ view.R[2]
    dx = flow[mask, 0]
    assert np.all(dx >= f * shift_m / depth.max() - 1e-6) and np.all(dx <= f * shift_m / depth.min() + 1e-6)
    np.testing.assert_allclose(flow[mask, 1], 0.0, atol=0.05)
    assert np.all(flow[~mask] == 0)


def test_build_entries_and_metadata():
    db = build_database(TINY, 3)
    assert len(db) == TINY.n_entries == 2 * 2 * 4 * 2
    assert set(db.motion.tolist()) == {"walk", "kick"}
    assert np.all((db.elevation_deg >= 0) & (db.elevation_deg <= 35))
    assert np.all(np.abs(db.azimuth_deg) <= 180)
    q = db.joints
    assert q.min() > -BOX_SLACK and q.max() < 1 + BOX_SLACK
    cover = db.descriptors.mean(axis=1) / 255
    assert np.all((cover > 0.2) & (cover < 0.9))
    assert db.flows is None


def test_mirror_entries():
    db = build_database(TINY, 3)
    a, b = 0, 1  # each view is followed by its mirror image
    assert db.source[b] == db.source[a] + " mirrored"
    assert db.azimuth_deg[b] == pytest.approx(-db.azimuth_deg[a], abs=1e-4)
    np.testing.assert_array_equal(descriptor_grid(db.descriptors[b]), descriptor_grid(db.descriptors[a])[:, ::-1])
    flip = SKELETON_14.flip_permutation
    np.testing.assert_allclose(db.joints[b, :, 0], 1 - db.joints[a, flip, 0], atol=1e-6)
    np.testing.assert_allclose(db.joints[b, :, 1], db.joints[a, flip, 1], atol=1e-6)


def test_build_is_deterministic_and_seeded():
    a = build_database(TINY, 3)
    b = build_database(TINY, 3)
    c = build_database(TINY, 4)
    np.testing.assert_array_equal(a.descriptors, b.descriptors)
    np.testing.assert_array_equal(a.joints, b.joints)
    assert not np.array_equal(a.descriptors, c.descriptors)


def test_build_with_flow():
    cfg = BuildConfig(motions=("run",), sequences_per_motion=1, frames_per_sequence=6, frame_stride=3,
                      views_per_pose=2, with_flow=True)
    db = build_database(cfg, 0)
    assert db.flows is not None and db.flows.shape == (len(db), 2560)
    first = np.flatnonzero(db.frame == 0)
    assert np.isnan(db.flows[first]).all()  # no previous frame: no flow
    moving = np.flatnonzero(db.frame == 3)
    assert np.abs(db.flows[moving].astype(float)).max() > 0.01


def test_bvh_files_are_rendered(tmp_path):
    from toolkit.motion import write_bvh

    props = BodyProportions.from_height(1.7)
    path = tmp_path / "walk.bvh"
    write_bvh(path, generate_motion("walk", props, 12, 25.0, 1), 25.0)
    cfg = BuildConfig(motions=(), views_per_pose=2, bvh_frame_stride=6)
    db = build_database(cfg, 0, bvh_files=[path])
    assert len(db) == 2 * 2 * 2 and set(db.motion.tolist()) == {"walk"}
    with pytest.raises(InputError, match="bvh_files"):
        build_database(cfg, 0, bvh_files=[tmp_path / "missing.bvh"])


def test_bad_configs():
    with pytest.raises(InputError, match="motions"):
        BuildConfig(motions=("moonwalk",))
    with pytest.raises(InputError, match="views_per_pose"):
        BuildConfig(views_per_pose=0)
    with pytest.raises(InputError, match="workers"):
        build_database(TINY, 0, workers=0)


def test_default_database_is_cached(tmp_path, monkeypatch):
    monkeypatch.setenv(CACHE_ENV, str(tmp_path))
    db, path = default_database(config=TINY, seed=1)
    assert path.parent == tmp_path and path.is_file()
    again, path2 = default_database(config=TINY, seed=1)
    assert path2 == path
    np.testing.assert_array_equal(again.descriptors, db.descriptors)
    explicit, p3 = default_database(tmp_path / "mine.npz", config=TINY, seed=1)
    assert p3 == tmp_path / "mine.npz" and len(SilhouetteDatabase.load(p3)) == len(explicit)


def test_small_database_fixture(walk_db):
    assert len(walk_db) == 960  # 2 people x 20 poses x 12 views x 2 (mirror), no view dropped
