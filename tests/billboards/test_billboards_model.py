"""Billboard data model, fan building, projective texturing and projection surfaces."""

from __future__ import annotations

import numpy as np
import pytest

from toolkit.billboards import (Billboard, BillboardConfig, billboard_frame, build_billboards, render_view,
                                warp_billboard)
from toolkit.errors import InputError
from toolkit.skeleton import SKELETON_14

#: Texture transfer through two bilinear resamplings of a smooth texture: mean colour error, 8-bit levels.
TRANSFER_TOL = 12.0
#: Overlap (IoU) of a billboard drawn into its own camera with its segment; only the
#: one-pixel rim of the bilinear alpha can differ.
SELF_IOU = 0.9


def _iou(a, b):
    return np.logical_and(a, b).sum() / max(np.logical_or(a, b).sum(), 1)


def _full(warp, size):
    w, h = size
    a = np.zeros((h, w), np.float32)
    rgb = np.zeros((h, w, 3), np.float32)
    x0, y0, x1, y1 = warp.roi
    a[y0:y1, x0:x1] = warp.alpha
    rgb[y0:y1, x0:x1] = warp.rgb
    return rgb, a


def test_billboard_rejects_bad_fields():
    good = dict(part=1, camera="c", corners=np.zeros((4, 3)), texture=np.zeros((4, 5, 3), np.uint8),
                alpha=np.zeros((4, 5), np.float32), normal=np.array([0, 0, 1.0]))
    Billboard(**good)
    with pytest.raises(InputError, match="texture"):
        Billboard(**{**good, "texture": np.zeros((4, 5), np.uint8)})
    with pytest.raises(InputError, match="alpha"):
        Billboard(**{**good, "alpha": np.zeros((5, 4), np.float32)})
    with pytest.raises(InputError, match="axis"):
        Billboard(**{**good, "surface": "cylinder"})


def test_frame_holds_the_bone_and_faces_the_camera():
    x, y, c = np.array([0, 0, 1.0]), np.array([0.1, 0, 1.3]), np.array([1.0, 5.0, 2.0])
    fr = billboard_frame(x, y, c)
    b = (y - x) / np.linalg.norm(y - x)
    assert np.allclose(fr.e_v, b)
    assert abs(fr.normal @ b) < 1e-12 and fr.normal @ (c - x) > 0
    # the plane holds b x (c - x)
    assert abs(fr.normal @ np.cross(b, c - x)) < 1e-12
    assert billboard_frame(x, x + 0.3 * (c - x) / np.linalg.norm(c - x), c) is None  # bone points at camera


def test_texture_maps_round_trip(planar_scene):
    m = build_billboards(planar_scene.images, planar_scene.labels, planar_scene.joints, planar_scene.rig)
    bb = m.fan(planar_scene.part).billboards[0]
    uv = np.array([[0.0, 0.0], [3.5, 7.25], [bb.size[0] - 1, bb.size[1] - 1]])
    X = np.c_[uv, np.ones(3)] @ bb.world_from_texture().T
    assert np.allclose(bb.texture_from_world(X), uv, atol=1e-9)
    cam = planar_scene.rig[0]
    q = np.c_[uv, np.ones(3)] @ bb.view_from_texture(cam).T
    assert np.allclose(q[:, :2] / q[:, 2:], cam.project(X), atol=1e-6)


def test_fan_coincides_with_the_plank(planar_scene):
    s = planar_scene
    m = build_billboards(s.images, s.labels, s.joints, s.rig)
    assert [f.part for f in m.fans] == [s.part]  # only the plank is labelled
    fan = m.fan(s.part)
    assert len(fan.billboards) == len(s.rig)
    plank_n = np.cross(s.corners[1] - s.corners[0], s.corners[3] - s.corners[0])
    plank_n /= np.linalg.norm(plank_n)
    for bb in fan.billboards:
        assert abs(abs(bb.normal @ plank_n) - 1) < 1e-9
        uv = bb.texture_from_world(s.corners)  # the plank lies inside the billboard
        assert np.all(uv > -1.5) and np.all(uv[:, 0] < bb.size[0] + 0.5) and np.all(uv[:, 1] < bb.size[1] + 0.5)


def test_warp_reproduces_source_and_transfers_texture(planar_scene):
    s = planar_scene
    m = build_billboards(s.images, s.labels, s.joints, s.rig)
    fan = m.fan(s.part)
    for bb in fan.billboards:
        for cam in s.rig:
            w = warp_billboard(bb, cam)
            rgb, a = _full(w, cam.size)
            seg = s.labels[cam.name] == s.part
            assert _iou(a >= 0.5, seg) > SELF_IOU
            inner = (a >= 0.99) & seg
            err = np.abs(rgb[inner] - s.images[cam.name][inner].astype(np.float32)).mean()
            assert err < TRANSFER_TOL, (bb.camera, cam.name, err)
            # the depth is the plank's
            d = w.depth[np.isfinite(w.depth)]
            mid = cam.depth_of(s.corners.mean(axis=0))
            assert np.all(np.abs(d - mid) < 0.2)


def test_warp_outside_or_behind_is_empty(planar_scene):
    s = planar_scene
    bb = build_billboards(s.images, s.labels, s.joints, s.rig).fan(s.part).billboards[0]
    cam = s.rig[0]
    behind = cam.replace(cam_from_world=np.diag([-1.0, 1.0, -1.0, 1.0]) @ cam.cam_from_world)
    assert warp_billboard(bb, behind).empty
    assert warp_billboard(bb, cam, roi=(0, 0, 5, 5)).empty


def test_render_view_covers_the_segment(planar_scene):
    s = planar_scene
    m = build_billboards(s.images, s.labels, s.joints, s.rig)
    for cam in s.rig:
        rgb, a, info = render_view(m, cam)
        seg = s.labels[cam.name] == s.part
        assert _iou(a >= 0.5, seg) > SELF_IOU
        assert set(np.unique(info.part)) == {0, s.part}


@pytest.mark.parametrize("surface", ["cylinder", "ellipsoid"])
def test_curved_surfaces_reproduce_their_source(planar_scene, surface):
    s = planar_scene
    cfg = BillboardConfig(surface=surface)
    m = build_billboards(s.images, s.labels, s.joints, s.rig, config=cfg)
    for bb in m.fan(s.part).billboards:
        assert bb.surface == surface and bb.radius > 0
        cam = s.rig[bb.camera]
        rgb, a = _full(warp_billboard(bb, cam), cam.size)
        seg = s.labels[cam.name] == s.part
        assert _iou(a >= 0.5, seg) > SELF_IOU - 0.05  # cells are drawn as planar pieces
        inner = (a >= 0.99) & seg
        assert np.abs(rgb[inner] - s.images[cam.name][inner]).mean() < TRANSFER_TOL


def test_build_rejects_bad_input(planar_scene):
    s = planar_scene
    with pytest.raises(InputError, match="images"):
        build_billboards({}, s.labels, s.joints, s.rig)
    with pytest.raises(InputError, match="joints3d"):
        build_billboards(s.images, s.labels, s.joints[:5], s.rig)
    with pytest.raises(InputError, match="non-finite"):
        build_billboards(s.images, s.labels, np.full((14, 3), np.nan), s.rig)


def test_corrected_cameras_follow_their_images(planar_scene):
    """Shifting an image by d pixels and its camera's principal point by d gives the same billboard texture."""
    from toolkit.cameras import Rig, camera_with_offset

    s = planar_scene
    d = np.array([3.0, -2.0])
    imgs, labs = dict(s.images), dict(s.labels)
    name = s.rig[0].name
    imgs[name] = np.roll(s.images[name], (int(d[1]), int(d[0])), axis=(0, 1))
    labs[name] = np.roll(s.labels[name], (int(d[1]), int(d[0])), axis=(0, 1))
    shifted = Rig((camera_with_offset(s.rig[0], d),) + tuple(s.rig)[1:])
    a = build_billboards(s.images, s.labels, s.joints, s.rig).fan(s.part).billboards[0]
    b = build_billboards(imgs, labs, s.joints, shifted).fan(s.part).billboards[0]
    assert a.texture.shape == b.texture.shape
    assert np.abs(a.texture.astype(int) - b.texture.astype(int)).mean() < 1.0


def test_model_reports_quads(planar_scene):
    from toolkit.observe import RecordingObserver
    s = planar_scene
    obs = RecordingObserver()
    build_billboards(s.images, s.labels, s.joints, s.rig, observer=obs)
    q = obs.of_kind("quads")[0]
    assert q["corners"].shape == (len(s.rig), 4, 3) and q["textures"][0].shape[2] == 4
    missing = obs.of_kind("text")
    assert len(missing) == len(s.rig) * (SKELETON_14.n_parts - 1)  # every other part: empty segment
