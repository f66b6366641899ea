"""Seeded masks on the Pose2Sim demo (real footage, no ground truth): hand-checkable properties."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

from toolkit.foreground import SeededSegmenter
from toolkit.io import Dataset, import_pose2sim_trial
from toolkit.io.keypoint_files import read_camera_detections
from toolkit.skeleton.mappings import to_skeleton14

REPO_ROOT = Path(__file__).resolve().parents[2]
TRIAL = Path("pose2sim_demo/S00_P00_SingleParticipant/S00_P00_T01_BalancingTrial")
#: The mask stays within the subject's keypoint box grown by this fraction of its height (hands,
#: feet, head top and a little leak; a mask spilling over the room would not).
BOX_GROWTH = 0.25
#: The subject covers at least this fraction of its keypoint box (a mask of a few limbs would not).
MIN_BOX_COVER = 0.25
#: Pixels of the bystander's keypoint box the mask may take, fraction of that box.
BYSTANDER_MAX = 0.02


def _trial() -> Path:
    env = os.environ.get("TOOLKIT_REALDATA")
    root = Path(env) if env else REPO_ROOT.parent / "shared" / "realdata"
    if not (root / TRIAL).is_dir():
        pytest.skip(f"real data not found at {root / TRIAL}")
    return root / TRIAL


def _box(j, grow=0.0):
    lo, hi = np.nanmin(j, 0), np.nanmax(j, 0)
    g = grow * (hi[1] - lo[1])
    return lo - g, hi + g


@pytest.mark.realdata
def test_demo_mask_is_the_subject_and_not_the_bystander(tmp_path):
    trial = _trial()
    import_pose2sim_trial(trial, tmp_path / "demo")
    with Dataset.open(tmp_path / "demo") as ds:
        cam = "cam_01"  # a bystander stands at the left of the room
        img = ds.frame(cam, 0)
        subject = to_skeleton14(read_camera_detections(ds.keypoint_dir(cam), max_frames=1).people[0][0], "body_25b",
                                confidence=True)
    raw = read_camera_detections(trial / "pose" / "cam01_json", max_frames=1).people[0]
    people = [to_skeleton14(p, "body_25b", confidence=True) for p in raw]
    centre = np.nanmean(subject[:, :2], 0)
    others = [np.where(p[:, 2:] > 0, p[:, :2], np.nan) for p in people
              if np.linalg.norm(np.nanmean(np.where(p[:, 2:] > 0, p[:, :2], np.nan), 0) - centre) > 200]
    assert len(others) == 1
    mask = SeededSegmenter().segment(img, subject[:, :2], subject[:, 2], others=others).mask
    ys, xs = np.nonzero(mask)
    joints = np.where(subject[:, 2:] > 0, subject[:, :2], np.nan)
    lo, hi = _box(joints, BOX_GROWTH)
    assert lo[0] <= xs.min() and xs.max() <= hi[0] and lo[1] <= ys.min() and ys.max() <= hi[1]
    lo, hi = _box(joints)
    inner = mask[int(lo[1]):int(hi[1]), int(lo[0]):int(hi[0])]
    assert inner.mean() >= MIN_BOX_COVER
    lo, hi = _box(others[0])
    theirs = mask[int(lo[1]):int(hi[1]), int(lo[0]):int(hi[0])]
    assert theirs.sum() <= BYSTANDER_MAX * theirs.size
