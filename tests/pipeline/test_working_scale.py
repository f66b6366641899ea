"""The working resolution of a frame's stages 2-3 (toolkit.pipeline.working_scale)."""

from types import SimpleNamespace

import numpy as np
import pytest

from tests.rendering.conftest import studio  # noqa: F401  (a fixture: registered by being imported here)
from toolkit.cameras import Camera, Rig
from toolkit.errors import InputError
from toolkit.pipeline.working_scale import WORK_HEIGHT_PX, WorkingFrame, person_extent_px, working_scales

#: A 1.7 m person standing at the origin: head at 1.6 m, ankles at 0.08 m (the extent the joints span).
JOINTS = np.array([[0.0, 0.0, 1.6], [0.0, 0.0, 1.45], [0.2, 0.0, 1.4], [-0.2, 0.0, 1.4], [0.25, 0.0, 1.1],
                   [-0.25, 0.0, 1.1], [0.3, 0.0, 0.85], [-0.3, 0.0, 0.85], [0.1, 0.0, 0.9], [-0.1, 0.0, 0.9],
                   [0.1, 0.0, 0.5], [-0.1, 0.0, 0.5], [0.1, 0.0, 0.08], [-0.1, 0.0, 0.08]])


def _rig():
    """A near camera (the person ~1150 px tall) and a far one (~190 px)."""
    near = Camera.look_at("near", [0.0, -2.0, 0.9], [0.0, 0.0, 0.9], size=(1080, 1920), focal_px=1500.0)
    far = Camera.look_at("far", [-12.0, 0.0, 0.9], [0.0, 0.0, 0.9], size=(1280, 720), focal_px=1500.0)
    return Rig((near, far))


def test_scales_bring_a_large_person_to_the_working_height_and_leave_a_small_one():
    rig = _rig()
    ext = [person_extent_px(c, JOINTS) for c in rig]
    assert ext[0] > 1000 and ext[1] < WORK_HEIGHT_PX
    s = working_scales(rig, JOINTS)
    assert s[0] == pytest.approx(WORK_HEIGHT_PX / ext[0]) and s[1] == 1.0
    assert np.all(working_scales(rig, JOINTS, None) == 1) and np.all(working_scales(rig, JOINTS, 0) == 1)
    assert np.all(working_scales(rig, np.full((14, 3), np.nan)) == 1)  # no joints: nothing to scale for
    with pytest.raises(InputError, match="work_height_px"):
        working_scales(rig, JOINTS, -5)


def test_working_pixels_are_where_the_working_camera_projects():
    rig = _rig()
    work = WorkingFrame.of(rig, working_scales(rig, JOINTS))
    assert work.scaled and work.rig["far"] is rig["far"]
    full = np.stack([c.project(JOINTS) for c in rig])
    small = np.stack([c.project(JOINTS) for c in work.rig])
    np.testing.assert_allclose(work.points(full), small, atol=1e-9)
    off = np.array([[3.0, -2.0], [np.nan, np.nan]])
    np.testing.assert_allclose(work.offsets(off)[0], off[0] * work.scales[0])
    assert np.isnan(work.offsets(off)[1]).all()
    with pytest.raises(InputError, match="scales"):
        WorkingFrame.of(rig, [0.5, 1.5])


def test_images_masks_and_labels_change_size_and_back():
    rig = _rig()
    work = WorkingFrame.of(rig, working_scales(rig, JOINTS))
    near = rig["near"]
    img = np.zeros(near.size[::-1] + (3,), np.uint8)
    small = work.images({"near": img, "far": np.zeros((720, 1280, 3), np.uint8)})
    assert small["near"].shape[1::-1] == work.rig["near"].size and small["far"].shape == (720, 1280, 3)
    mask = np.zeros(near.size[::-1], bool)
    mask[400:1500, 300:700] = True
    m_small = work.masks([mask, None])
    assert m_small[1] is None and m_small[0].shape[::-1] == work.rig["near"].size
    assert abs(m_small[0].mean() - mask.mean()) < 0.01
    labels = {"near": np.where(m_small[0], 3, 0).astype(np.uint8), "far": np.zeros((720, 1280), np.uint8)}
    up = work.full_labels(labels)
    assert up["near"].shape == mask.shape and up["far"] is labels["far"]
    on = work.full_labels(labels, [mask, None])
    # on the full silhouette: its pixels exactly (they all lie within one working pixel of a labelled one)
    assert np.array_equal(on["near"] > 0, mask) and set(np.unique(on["near"])) == {0, 3}


def test_supersample_keeps_texels_per_full_pixel_and_one_unscaled_camera_keeps_all():
    rig = _rig()
    assert WorkingFrame.of(rig, [0.3, 1.0]).supersample(6) == 6
    assert WorkingFrame.of(rig, [0.3, 0.3]).supersample(6) == 2
    assert WorkingFrame.of(rig, [0.05, 0.05]).supersample(6) == 1


def test_frame_at_a_working_scale_comes_back_at_full_resolution(studio):
    """A frame processed with the person brought to 60 px: labels, cameras and billboards at the cameras' own
    size, the silhouettes' edges kept, the novel view close to the full-resolution one."""
    from toolkit.observe import RecordingObserver
    from toolkit.pipeline.frame import FrameProcessor
    from toolkit.rendering.freeviewpoint import FreeViewpointConfig, render_methods

    t, rig = 1, studio.gt_rig
    images = {c: studio.frame(c, t) for c in rig.names}
    masks = [studio.gt_parts(c, t) > 0 for c in rig.names]
    J = studio.gt_joints3d()[t]
    est = SimpleNamespace(ok=True, joints3d=J, offsets=np.zeros((3, 2)), poses2d=np.full((3, 14, 2), np.nan))
    ext = min(person_extent_px(c, J) for c in rig)
    assert ext > 80  # the test scene's person; 60 px scales every camera
    cfg = FreeViewpointConfig(optimize=False, work_height_px=60)
    obs = RecordingObserver()
    small = FrameProcessor(rig, cfg, observer=obs).process(t, images, masks, est)
    full = FrameProcessor(rig, FreeViewpointConfig(optimize=False, work_height_px=None)).process(t, images, masks, est)
    same = FrameProcessor(rig, FreeViewpointConfig(optimize=False, work_height_px=1000)).process(t, images, masks, est)
    assert small.ok and small.model.rig is small.cameras  # the billboards keep the full-resolution cameras
    for c, m in zip(rig.names, masks):
        assert small.labels[c].shape == m.shape and small.cameras[c].size == rig[c].size
        assert np.array_equal(same.labels[c], full.labels[c])  # a person under work_height_px: unchanged
        assert (small.labels[c] > 0).sum() == pytest.approx(m.sum(), rel=0.05)
    assert all(r["labels"].shape == rig[r["camera"]].size[::-1] for r in obs.of_kind("labels") if "camera" in r)
    cam = rig[0]
    bg = np.zeros(cam.size[::-1] + (3,), np.uint8)
    a = render_methods(small, cam, bg)["articulated"].astype(float)
    b = render_methods(full, cam, bg)["articulated"].astype(float)
    psnr = 10 * np.log10(255.0 ** 2 / np.mean((a - b) ** 2))
    assert psnr > 25.0, psnr


def test_labels_come_back_with_smooth_boundaries_not_the_working_staircase():
    """Two parts split by a slanted line, and a thin limb, at a third of the size and back: the boundary
    follows the line within a pixel or so, better than nearest resizing, and every label survives."""
    import cv2

    from toolkit.pipeline.working_scale import upsample_labels

    H, W = 600, 420
    yy, xx = np.mgrid[0:H, 0:W]
    full = np.zeros((H, W), np.uint8)
    body = (xx > 60) & (xx < 360) & (yy > 40) & (yy < 560)
    full[body] = np.where(yy[body] < 0.6 * xx[body] + 150, 1, 2)
    full[(np.abs(xx - 0.3 * yy - 30) < 5) & (yy > 100) & (yy < 500)] = 7  # a limb 10 px wide
    small = cv2.resize(full, (W // 3, H // 3), interpolation=cv2.INTER_NEAREST)
    smooth = upsample_labels(small, (W, H))
    nearest = cv2.resize(small, (W, H), interpolation=cv2.INTER_NEAREST)
    assert smooth.shape == (H, W) and smooth.dtype == np.uint8
    assert set(np.unique(smooth)) == {0, 1, 2, 7}

    def iou(a, lab):
        return ((a == lab) & (full == lab)).sum() / ((a == lab) | (full == lab)).sum()

    for lab in (1, 2, 7):
        assert iou(smooth, lab) >= iou(nearest, lab) - 1e-9
    assert iou(smooth, 7) > iou(nearest, 7) + 0.02 and iou(smooth, 7) > 0.6
    assert np.mean(smooth != full) < np.mean(nearest != full)
    assert not upsample_labels(np.zeros((20, 10), np.uint8), (30, 60)).any()
    # a constant labelled image stays constant
    assert (upsample_labels(np.full((20, 10), 4, np.uint8), (30, 60)) == 4).all()
