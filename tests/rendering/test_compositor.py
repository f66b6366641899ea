import numpy as np
import pytest

from toolkit.observe import RecordingObserver
from toolkit.rendering import CpuCompositor, psnr, standard_billboards
from toolkit.rendering.blend import STATUS_ALL_BEHIND, STATUS_EMPTY_MODEL

#: Required reproduction of a source image inside the subject's mask (issue 6).
REPRODUCTION_PSNR_DB = 40.0
#: Reproduction with stage-3 textures (one texel per source pixel, resampled twice): measured 31-35 dB.
STAGE3_TEXTURE_PSNR_DB = 28.0
#: Stray coverage tolerated outside the subject's mask on a source view (mean alpha).
OUTSIDE_ALPHA = 0.01


@pytest.mark.parametrize("cam_index", [0, 1, 2])
def test_virtual_camera_on_source_reproduces_it(studio_frame, studio_model, cam_index):
    f = studio_frame
    cam = f["rig"][cam_index]
    r = CpuCompositor().render(studio_model, cam)
    assert r.ok
    img = f["images"][cam.name]
    out = r.over(np.zeros_like(img))
    mask = f["masks"][cam.name]
    assert psnr(out, img, mask) > REPRODUCTION_PSNR_DB
    assert r.alpha[mask].mean() > 0.99
    assert r.alpha[~mask].mean() < OUTSIDE_ALPHA
    assert not r.smoothed.any()  # no smoothing on a source camera


def test_standard_billboards_reproduce_source(studio_frame):
    f = studio_frame
    m = standard_billboards(f["images"], f["masks"], f["joints"], f["rig"])
    cam = f["rig"][0]
    r = CpuCompositor().render(m, cam)
    out = r.over(np.zeros_like(f["images"][cam.name]))
    assert psnr(out, f["images"][cam.name], f["masks"][cam.name]) > REPRODUCTION_PSNR_DB


#: Margin by which articulated billboards must beat standard billboards on a novel view (issue 6 target).
ARTICULATED_GAIN_DB = 2.0


def test_novel_view_beats_standard_billboards_and_reports(studio, studio_frame, studio_model):
    from toolkit.rendering import bbox_scores
    from toolkit.rendering.evaluation import BackgroundPlates

    f = studio_frame
    cam = studio.novel_rig[0]
    bg = BackgroundPlates(studio.root / "scene.toml").plate(cam)
    gt = studio.novel_image(cam.name, f["t"])
    gt_mask = studio.novel_mask(cam.name, f["t"])
    obs = RecordingObserver()
    r = CpuCompositor().render(studio_model, cam, observer=obs, frame=f["t"])
    art = bbox_scores(r.over(bg), gt, gt_mask)
    std_model = standard_billboards(f["images"], f["masks"], f["joints"], f["rig"])
    std = bbox_scores(CpuCompositor().render(std_model, cam).over(bg), gt, gt_mask)
    assert art["psnr"] > std["psnr"] + ARTICULATED_GAIN_DB
    assert art["ssim"] > std["ssim"]
    assert r.smoothed.any() and r.discontinuities.any()
    assert {"mask", "labels", "scalar"} <= obs.kinds
    assert len(r.order) >= 8


def test_camera_behind_everything_gives_an_empty_marked_frame(studio_model):
    from toolkit.cameras import Camera

    # put it 30 m behind the subject, looking away from it
    far = Camera.look_at("away", [0.0, -30.0, 1.0], [0.0, -60.0, 1.0], size=(64, 48), focal_px=60)
    r = CpuCompositor().render(studio_model, far)
    assert r.status == STATUS_ALL_BEHIND and r.alpha.max() == 0


def test_empty_model(studio_model):
    from toolkit.billboards.model import BillboardModel

    empty = BillboardModel((), studio_model.rig, 0)
    r = CpuCompositor().render(empty, studio_model.rig[0])
    assert r.status == STATUS_EMPTY_MODEL and not r.ok


def test_subject_missing_in_one_view_still_renders(studio, studio_frame):
    from toolkit.rendering import render_billboards

    f = studio_frame
    gone = f["rig"].names[2]
    labels = {c: (np.zeros_like(v) if c == gone else v) for c, v in f["labels"].items()}
    model = render_billboards(f["images"], labels, f["joints"], f["rig"], supersample=1)
    assert gone not in {b.camera for b in model.billboards} and len(model.billboards) > 0
    std = standard_billboards(f["images"], {c: labels[c] > 0 for c in labels}, f["joints"], f["rig"])
    assert gone not in std.fans[0].cameras
    r = CpuCompositor().render(model, studio.novel_rig[0])
    assert r.ok and r.alpha.max() > 0.99
    # the two remaining cameras still reproduce themselves
    cam = f["rig"][0]
    out = CpuCompositor().render(model, cam).over(np.zeros_like(f["images"][cam.name]))
    assert psnr(out, f["images"][cam.name], f["masks"][cam.name]) > STAGE3_TEXTURE_PSNR_DB


def test_two_subjects_nearer_one_occludes(studio_frame, studio_model):
    from toolkit.rendering import composite_subjects

    f = studio_frame
    cam = f["rig"][0]
    near = CpuCompositor().render(studio_model, cam)
    # a second, uniformly red subject layer covering the whole image, farther away
    far = near.__class__(np.full_like(near.rgb, 0) + np.array([255, 0, 0], np.float32), np.ones_like(near.alpha),
                         near.fan, near.dominant, near.discontinuities, near.smoothed, None, ())
    bg = np.zeros_like(f["images"][cam.name])
    img = composite_subjects([far, near], [10.0, 5.0], bg)
    mask = f["masks"][cam.name]
    assert psnr(img, f["images"][cam.name], mask) > REPRODUCTION_PSNR_DB  # the nearer subject is on top
    assert np.all(img[~mask & (near.alpha == 0)] == [255, 0, 0])
    swapped = composite_subjects([far, near], [5.0, 10.0], bg)  # now the red layer is in front
    assert np.all(swapped == [255, 0, 0])
