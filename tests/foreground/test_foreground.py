"""Foreground extraction against ground-truth masks of synthetic videos."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from foreground_scenes import SIZE, draw_figure, moving_figure_video, textured_background

from toolkit.errors import InputError
from toolkit.foreground import (
    BackgroundConfig,
    BackgroundModel,
    ChromaKeyConfig,
    ForegroundConfig,
    ForegroundExtractor,
    MorphologyConfig,
    MotionConfig,
    SilhouetteConfig,
    bounding_box,
    chroma_key,
    clean_mask,
    extract_silhouettes,
    fill_holes,
    keep_largest_components,
    mask_iou,
    silhouette_from_mask,
    warp_previous_mask,
)
from toolkit.observe import RecordingObserver

#: Mean IoU of the median and MOG2 models on the moving-figure fixture (measured 0.996 over
#: 8 seeds, worst frame 0.992; the 1-pixel opening and closing round the limb ends).
MEAN_IOU = 0.98
#: Worst frame IoU on the fixture.
WORST_IOU = 0.95
#: Chroma key on a noisy green screen (measured 0.997 after clean-up).
CHROMA_IOU = 0.97


@pytest.mark.parametrize("method", ["median", "mog2"])
def test_background_subtraction_iou(method):
    ious = []
    for seed in range(3):
        frames, gt = moving_figure_video(seed, n_frames=30)
        sils = extract_silhouettes(frames, ForegroundConfig(background=BackgroundConfig(method=method)))
        ious += [mask_iou(s.mask, g) for s, g in zip(sils, gt)]
        assert all(s.state == "ok" for s in sils)
    assert np.mean(ious) > MEAN_IOU
    assert np.min(ious) > WORST_IOU


def test_median_is_the_default_and_beats_knn():
    """The default was picked by measured IoU (docs/stage1_multiview.md): KNN is far worse here."""
    assert ForegroundConfig().background.method == "median"
    frames, gt = moving_figure_video(1, n_frames=30)
    iou = {m: np.mean([mask_iou(s.mask, g) for s, g in zip(
        extract_silhouettes(frames, ForegroundConfig(background=BackgroundConfig(method=m))), gt)])
        for m in ("median", "knn")}
    assert iou["median"] > iou["knn"] + 0.1


def test_motion_compensation_keeps_iou(figure_video):
    frames, gt = figure_video
    cfg = ForegroundConfig(motion=MotionConfig(enabled=True))
    sils = extract_silhouettes(frames, cfg)
    assert np.mean([mask_iou(s.mask, g) for s, g in zip(sils, gt)]) > MEAN_IOU


def test_motion_compensation_helps_a_camouflaged_subject():
    """A figure whose colours are close to the background: the warped previous mask lowers
    the threshold where the subject is expected (measured +0.15 mean IoU over 8 seeds)."""
    gains = []
    for seed in range(3):
        rng = np.random.default_rng(100 + seed)
        bg = textured_background(rng)
        mean = bg.reshape(-1, 3).mean(0)
        cols = [np.clip(mean + rng.uniform(-20, 20, 3), 0, 255) for _ in range(3)]
        frames, gt = moving_figure_video(seed, n_frames=20, colors=cols, background=bg)
        iou = [np.mean([mask_iou(s.mask, g) for s, g in zip(extract_silhouettes(
            frames, ForegroundConfig(motion=MotionConfig(enabled=on))), gt)]) for on in (False, True)]
        gains.append(iou[1] - iou[0])
    assert np.mean(gains) > 0.05


def test_warp_previous_mask_follows_motion():
    rng = np.random.default_rng(0)
    h, w = 96, 128
    tex = cv2.GaussianBlur(rng.uniform(0, 255, (h, w, 3)), (0, 0), 1.5)
    prev = np.clip(tex, 0, 255).astype(np.uint8)
    cur = np.roll(prev, (3, 5), axis=(0, 1))   # the whole image moves by (dx, dy) = (5, 3)
    mask = np.zeros((h, w), bool)
    mask[30:60, 40:70] = True
    for method in ("dis", "farneback"):
        warped = warp_previous_mask(mask, prev, cur, method)
        assert mask_iou(warped, np.roll(mask, (3, 5), axis=(0, 1))) > 0.9


def test_chroma_key():
    rng = np.random.default_rng(5)
    w, h = SIZE
    green = np.clip(np.array([40.0, 170.0, 60.0]) + rng.normal(0, 8, (h, w, 3)), 0, 255)
    gt = draw_figure(green, 80, 0.3, [(200, 40, 40), (30, 30, 90), (230, 190, 160)])
    img = np.clip(green, 0, 255).astype(np.uint8)
    assert mask_iou(chroma_key(img), gt) > CHROMA_IOU
    sils = extract_silhouettes(img[None], ForegroundConfig(method="chroma"))
    assert mask_iou(sils[0].mask, gt) > CHROMA_IOU
    # a blue screen is not keyed by the green defaults, but by a blue range
    blue = np.full((h, w, 3), (30, 60, 200), np.uint8)
    assert chroma_key(blue).all()
    assert not chroma_key(blue, ChromaKeyConfig(hue_range=(95, 130))).any()


def test_states_empty_full_border():
    frames, gt = moving_figure_video(2, n_frames=12, x_range=(-60, 220))  # walks in and out
    sils = extract_silhouettes(frames, ForegroundConfig())
    assert sils[0].state == "empty" and sils[0].bbox is None and not sils[0]
    assert sils[-1].state == "empty"
    assert any(s.state == "touches_border" for s in sils)
    assert any(s.state == "ok" for s in sils)
    # a sudden global change (lights, camera moved): the whole frame differs
    ex = ForegroundExtractor().fit(frames)
    full = ex.extract(255 - frames[5])
    assert full.state == "full" and not full
    blank = silhouette_from_mask(np.zeros((10, 12), bool))
    assert blank.state == "empty" and blank.bbox is None and blank.area_px == 0


def test_silhouette_bbox_and_state_ok():
    m = np.zeros((40, 50), bool)
    m[10:30, 5:20] = True
    s = silhouette_from_mask(m)
    assert s.bbox == (5, 10, 20, 30) and s.state == "ok" and s.area_px == 300
    assert bounding_box(m) == (5, 10, 20, 30)
    assert s.mask[s.bbox[1]:s.bbox[3], s.bbox[0]:s.bbox[2]].all()
    edge = np.zeros((40, 50), bool)
    edge[0:20, 5:20] = True
    assert silhouette_from_mask(edge).state == "touches_border"
    small = np.zeros((40, 50), bool)
    small[5:7, 5:7] = True
    assert silhouette_from_mask(small, SilhouetteConfig(min_area_px=10)).state == "empty"


def test_morphology():
    m = np.zeros((60, 60), bool)
    m[10:50, 20:35] = True
    m[2, 2] = True                              # isolated noise
    m[20:30, 40:44] = True                      # a limb cut off by a 5 px gap
    m[5:7, 55:57] = True                        # a far blob
    out = clean_mask(m)
    assert not out[2, 2] and out[21, 41] and not out[5, 55]
    assert out[11:49, 21:34].all()          # corners of the block are rounded by the opening
    # without merging, only the largest component is kept
    assert not clean_mask(m, MorphologyConfig(merge_fraction=0.0))[21, 41]
    ring = np.zeros((30, 30), bool)
    ring[5:25, 5:25] = True
    ring[10:20, 10:20] = False
    assert fill_holes(ring)[15, 15] and not ring[15, 15]
    kept = keep_largest_components(m, 2)
    assert kept[20, 25] and kept[21, 41] and not kept[2, 2]


def test_observer_reports(figure_video):
    frames, _ = figure_video
    obs = RecordingObserver()
    extract_silhouettes(frames[:5], ForegroundConfig(), camera="cam0", observer=obs)
    masks = obs.of_kind("mask")
    assert len(masks) == 5 and masks[0]["camera"] == "cam0" and masks[0]["frame"] == 0
    boxes = obs.of_kind("boxes2d")
    assert boxes and boxes[0]["mins"].shape == (1, 2)
    assert {d["name"] for d in obs.of_kind("scalar")} == {"foreground/area_fraction/cam0"}


def test_bad_input():
    frames, _ = moving_figure_video(0, n_frames=5)
    with pytest.raises(InputError, match="frame"):
        ForegroundExtractor().extract(frames[0])           # no background learned
    ex = ForegroundExtractor().fit(frames)
    with pytest.raises(InputError, match="frame"):
        ex.extract(frames[0][..., 0])                       # grey, not RGB
    with pytest.raises(InputError, match="frame"):
        ex.extract(frames[0][:50])                          # another size
    with pytest.raises(InputError, match="frame"):
        ex.extract(frames[0].astype(np.float32))
    with pytest.raises(InputError, match="frames"):
        BackgroundModel.fit(frames[:0])
    with pytest.raises(InputError, match="frames"):
        BackgroundModel.fit(iter(frames))
    with pytest.raises(InputError, match="mask"):
        silhouette_from_mask(np.zeros((3, 3, 3)))
    with pytest.raises(InputError, match="previous_mask"):
        warp_previous_mask(np.zeros((5, 5), bool), frames[0], frames[1])


@pytest.mark.parametrize("make", [
    lambda: BackgroundConfig(method="gmm"),
    lambda: BackgroundConfig(n_samples=0),
    lambda: BackgroundConfig(min_threshold=-1),
    lambda: ChromaKeyConfig(hue_range=(0, 200)),
    lambda: MorphologyConfig(open_radius_px=-1),
    lambda: MorphologyConfig(min_component_fraction=2),
    lambda: MotionConfig(method="lk"),
    lambda: MotionConfig(prior_threshold_scale=0),
    lambda: SilhouetteConfig(full_fraction=0),
    lambda: ForegroundConfig(method="depth"),
])
def test_bad_config(make):
    with pytest.raises(InputError):
        make()
