"""Subject masks seeded by 2D keypoints (toolkit.foreground.seeded), against rendered ground truth."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from toolkit.errors import InputError
from toolkit.foreground import mask_iou
from toolkit.foreground.seeded import (
    RefineConfig,
    SeededConfig,
    SeededMask,
    SeededSegmenter,
    body_scale,
    refine_masks,
    seed_trimap,
)
from toolkit.io import Dataset
from toolkit.observe import RecordingObserver
from toolkit.synthetic import generate_scene, parse_spec

#: A studio scene the defaults were not tuned on (tuning: seeds 101, 102), a subject that barely moves.
SPEC = """
seed = 7
frames = 3
fps = 25
[subject]
height_m = 1.75
motion = "idle"
[cameras]
count = 3
layout = "studio"
resolution = [480, 270]
calibration_error_px = 0.0
[novel]
count = 0
"""
#: Keypoint noise, pixels (a subject about 100 px tall: about 1.5 % of its height, as OpenPose on
#: the Pose2Sim demo is 8-17 px on a 1300 px person).
NOISE_PX = 1.5
#: IoU with the true masks over 3 frames x 3 cameras: measured median 0.913, worst 0.829 (mp4v
#: frames, noisy keypoints); the bounds leave room for encoder differences, not for a broken cut.
IOU_MEDIAN_MIN = 0.87
IOU_WORST_MIN = 0.78
#: The cut must beat its own seeds (the probable region of the trimap: IoU 0.52 here) by this.
CUT_GAIN_MIN = 0.15
#: Bystander pixels the mask may take, fraction of the bystander's area.
BYSTANDER_MAX = 0.02
#: How far beyond the true silhouette the hull may reach, pixels: the other views' tolerance
#: (MASK_TOLERANCE_PX = 3), a 2 cm voxel (about 3 px here) and its splat (about 2 px).
HULL_REACH_PX = 8
#: IoU the subject's mask may lose next to a bystander: the bystander here is a copy of the
#: subject, so its colours (sure background) are the subject's own: the hardest case (measured 0.07).
BYSTANDER_IOU_LOSS = 0.1
#: Carving the true masks with their own hull keeps this fraction of their pixels at least.
HULL_KEEPS_MIN = 0.97


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    out = tmp_path_factory.mktemp("seeded") / "scene"
    generate_scene(parse_spec(SPEC, "seeded.toml"), out, progress=False).close()
    ds = Dataset.open(out)
    rng = np.random.default_rng(0)
    j2 = {c: a + rng.normal(0, NOISE_PX, a.shape) for c, a in ds.gt_joints2d().items()}
    frames = {c: [ds.frame(c, t) for t in range(ds.n_frames)] for c in ds.camera_names}
    truth = {c: [ds.gt_mask(c, t) for t in range(ds.n_frames)] for c in ds.camera_names}
    yield ds, j2, frames, truth
    ds.close()


@pytest.fixture(scope="module")
def segmented(scene):
    ds, j2, frames, truth = scene
    seg = SeededSegmenter()
    return {c: seg.segment_sequence(frames[c], j2[c], camera=c) for c in ds.camera_names}


def test_masks_match_the_truth(scene, segmented):
    ds, j2, frames, truth = scene
    ious, seeds = [], []
    for c in ds.camera_names:
        for t in range(ds.n_frames):
            ious.append(mask_iou(segmented[c][t], truth[c][t]))
            tri = seed_trimap(truth[c][t].shape, j2[c][t])
            seeds.append(mask_iou((tri == cv2.GC_FGD) | (tri == cv2.GC_PR_FGD), truth[c][t]))
    assert np.median(ious) >= IOU_MEDIAN_MIN and min(ious) >= IOU_WORST_MIN, ious
    assert np.median(ious) >= np.median(seeds) + CUT_GAIN_MIN, (ious, seeds)


def test_bystanders_are_not_the_subject(scene):
    ds, j2, frames, truth = scene
    c, t = ds.camera_names[0], 0
    img, gt, j = frames[c][t], truth[c][t], j2[c][t]
    s = body_scale(j)
    xs = np.flatnonzero(gt.any(0))
    seg = SeededSegmenter()
    alone = mask_iou(seg.segment(img, j).mask, gt)
    for gap, with_keypoints in ((3.0, False), (0.3, True)):  # far away / beside the subject, in the band
        shift = int(xs.max() - xs.min() + gap * s)
        if xs.max() + shift >= img.shape[1]:
            shift = -shift
        other = np.roll(gt, shift, axis=1)
        assert not (other & gt).any()
        scene_img = img.copy()
        scene_img[other] = np.roll(img, shift, axis=1)[other]
        others = [j + [shift, 0]] if with_keypoints else ()
        m = seg.segment(scene_img, j, others=others).mask
        assert (m & other).sum() <= BYSTANDER_MAX * other.sum(), (gap, (m & other).sum(), other.sum())
        assert mask_iou(m, gt) >= alone - BYSTANDER_IOU_LOSS


def test_previous_frame_and_observer(scene):
    ds, j2, frames, truth = scene
    c = ds.camera_names[1]
    obs = RecordingObserver()
    seg = SeededSegmenter(observer=obs)
    first = seg.segment(frames[c][0], j2[c][0], camera=c, frame=0)
    assert isinstance(first, SeededMask) and len(first.models) == 2 and first.models[0][0].shape == (1, 65)
    second = seg.segment(frames[c][1], j2[c][1], previous=first, camera=c, frame=1)
    third = seg.segment(frames[c][1], j2[c][1], previous=first.mask)
    for r in (second, third):
        assert mask_iou(r.mask, truth[c][1]) >= IOU_WORST_MIN
    names = [d["name"] for d in obs.of_kind("mask")]
    assert names == ["seeded/trimap", "seeded/mask"] * 2


def test_refine_removes_what_the_other_views_do_not_see(scene, segmented):
    ds, j2, frames, truth = scene
    t = 0
    j3 = ds.gt_joints3d()[t]
    gt = {c: truth[c][t] for c in ds.camera_names}
    kept = refine_masks(gt, ds.gt_rig, j3)
    for c in ds.camera_names:
        assert kept[c].sum() >= HULL_KEEPS_MIN * gt[c].sum()
    # a blob of background above the head in one view, joined to it (a lamp, a bright wall patch):
    # no other view sees anything there.  (Beside the body the hull of two other views is 2-4 times
    # wider than the body on this ring of three cameras, so carving there needs more cameras.)
    c = ds.camera_names[2]
    ys, xs = np.nonzero(gt[c])
    top, mid = ys.min(), int(np.median(xs[ys < ys.min() + 5]))
    blob = np.zeros_like(gt[c])
    blob[top - 16:top + 2, mid - 8:mid + 8] = True
    blob &= ~gt[c]
    bad = dict(gt, **{c: gt[c] | blob})
    obs = RecordingObserver()
    out = refine_masks(bad, ds.gt_rig, j3, observer=obs, frame=t)
    far = blob & (cv2.distanceTransform((~gt[c]).astype(np.uint8), cv2.DIST_L2, 5) > HULL_REACH_PX)
    assert far.sum() > 100 and (out[c] & far).sum() <= 0.02 * far.sum()
    assert mask_iou(out[c], gt[c]) > mask_iou(bad[c], gt[c])
    assert len(obs.of_kind("mask")) == 3 and obs.of_kind("points3d")[0]["points"].shape[1] == 3
    seg_ref = refine_masks({k: segmented[k][t] for k in ds.camera_names}, ds.gt_rig, j3)
    for k in ds.camera_names:
        assert not (seg_ref[k] & ~segmented[k][t]).any()  # carving only removes


def test_no_pose_gives_an_empty_mask_and_bad_input_is_refused(scene):
    ds, j2, frames, truth = scene
    img = frames[ds.camera_names[0]][0]
    seg = SeededSegmenter()
    assert not seg.segment(img, np.full((14, 2), np.nan)).mask.any()
    with pytest.raises(InputError, match="joints2d"):
        seg.segment(img, np.zeros((13, 2)))
    with pytest.raises(InputError, match="weights"):
        seg.segment(img, j2[ds.camera_names[0]][0], -np.ones(14))
    with pytest.raises(InputError, match="previous"):
        seg.segment(img, j2[ds.camera_names[0]][0], previous=np.zeros((5, 5), bool))
    with pytest.raises(InputError, match="sure_scale"):
        SeededConfig(sure_scale=2.0)
    with pytest.raises(InputError, match="voxel_m"):
        RefineConfig(voxel_m=0.0)
    c = ds.camera_names[0]
    with pytest.raises(InputError, match="at least two"):
        refine_masks({c: truth[c][0]}, ds.rig, ds.gt_joints3d()[0])
    with pytest.raises(InputError, match="shape"):
        refine_masks({c: truth[c][0], ds.camera_names[1]: np.zeros((4, 4), bool)}, ds.rig, ds.gt_joints3d()[0])


def test_segment_views_carves_and_chains(scene, segmented):
    ds, j2, frames, truth = scene
    seg = SeededSegmenter()
    images = {c: frames[c][0] for c in ds.camera_names}
    joints = {c: j2[c][0] for c in ds.camera_names if c != ds.camera_names[2]}  # the third camera lost the pose
    masks, results = seg.segment_views(images, joints, rig=ds.rig, joints3d=ds.gt_joints3d()[0])
    assert not masks[ds.camera_names[2]].any()
    for c in ds.camera_names[:2]:
        assert not (masks[c] & ~results[c].mask).any()
        assert mask_iou(masks[c], truth[c][0]) >= IOU_WORST_MIN
    masks1, _ = seg.segment_views({c: frames[c][1] for c in ds.camera_names}, {c: j2[c][1] for c in ds.camera_names},
                                  previous=results)
    for c in ds.camera_names:  # no carving without a rig: the same masks as frame by frame (reproducible)
        assert not (masks1[c] ^ segmented[c][1]).any()
