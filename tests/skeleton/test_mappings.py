"""Keypoint conventions (OpenPose BODY_25/BODY_25B, COCO-17, CMU BVH) mapped to the 14 joints."""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import pytest

from toolkit.errors import InputError
from toolkit.skeleton import JOINTS_14
from toolkit.skeleton.mappings import (
    BODY_25,
    BODY_25B,
    CMU_BVH,
    COCO_17,
    FORMATS,
    KEYPOINTS,
    MAPPINGS,
    mapping_table,
    to_skeleton14,
)

REPO_ROOT = Path(__file__).resolve().parents[2]
J = {n: i for i, n in enumerate(JOINTS_14)}
EXACT = 1e-12


def realdata_root() -> Path:
    env = os.environ.get("TOOLKIT_REALDATA")
    return Path(env) if env else REPO_ROOT.parent / "shared" / "realdata"


def test_keypoint_counts_and_known_ids():
    assert len(BODY_25) == 25 and len(BODY_25B) == 25 and len(COCO_17) == 17 and len(CMU_BVH) == 38
    for names in KEYPOINTS.values():
        assert len(set(names)) == len(names)
    # spot checks of the official orders
    assert BODY_25[1] == "Neck" and BODY_25[8] == "MidHip" and BODY_25[4] == "RWrist" and BODY_25[24] == "RHeel"
    assert BODY_25B[:17] == tuple(
        "Nose LEye REye LEar REar LShoulder RShoulder LElbow RElbow LWrist RWrist LHip RHip LKnee RKnee "
        "LAnkle RAnkle".split())
    assert BODY_25B[17] == "UpperNeck" and BODY_25B[18] == "HeadTop"
    assert COCO_17[5] == "left_shoulder" and COCO_17[16] == "right_ankle"


@pytest.mark.parametrize("fmt", FORMATS)
def test_mapping_tables_are_complete_and_normalised(fmt):
    table = MAPPINGS[fmt]
    assert set(table) == set(JOINTS_14)
    for joint, alts in table.items():
        assert alts, joint
        for alt in alts:
            assert set(alt) <= set(KEYPOINTS[fmt]), (joint, alt)
            assert sum(alt.values()) == pytest.approx(1.0, abs=EXACT)
    assert mapping_table(fmt).count("\n") == 15


def keypoints_from(fmt, named: dict, dim=3):
    """An array of NaN with the given named keypoints set."""
    k = np.full((len(KEYPOINTS[fmt]), dim), np.nan)
    for n, v in named.items():
        k[KEYPOINTS[fmt].index(n)] = v
    return k


OPENPOSE_LIMBS = {"LShoulder": "l_shoulder", "RShoulder": "r_shoulder", "LElbow": "l_elbow",
                  "RElbow": "r_elbow", "LWrist": "l_wrist", "RWrist": "r_wrist", "LHip": "l_hip",
                  "RHip": "r_hip", "LKnee": "l_knee", "RKnee": "r_knee", "LAnkle": "l_ankle",
                  "RAnkle": "r_ankle"}


@pytest.mark.parametrize("fmt", ["body_25", "body_25b"])
def test_openpose_limbs_map_one_to_one(fmt):
    rng = np.random.default_rng(0)
    named = {n: rng.normal(size=3) for n in KEYPOINTS[fmt]}
    out = to_skeleton14(keypoints_from(fmt, named), fmt)
    for src, ours in OPENPOSE_LIMBS.items():
        np.testing.assert_allclose(out[J[ours]], named[src], atol=EXACT)
    np.testing.assert_allclose(out[J["head"]], 0.5 * (named["LEar"] + named["REar"]), atol=EXACT)
    neck = named["Neck"] if fmt == "body_25" else named["UpperNeck"]
    np.testing.assert_allclose(out[J["neck"]], neck, atol=EXACT)


def test_coco_neck_is_mean_of_shoulders_and_head_falls_back():
    pts = {"left_shoulder": [2.0, 0, 0], "right_shoulder": [0.0, 2, 0], "left_ear": [1.0, 1, 1],
           "right_ear": [3.0, 1, 1], "left_eye": [0.0, 0, 4], "right_eye": [2.0, 0, 4], "nose": [5.0, 5, 5]}
    k = keypoints_from("coco_17", pts)
    out = to_skeleton14(k, "coco_17")
    np.testing.assert_allclose(out[J["neck"]], [1, 1, 0], atol=EXACT)
    np.testing.assert_allclose(out[J["head"]], [2, 1, 1], atol=EXACT)            # ears
    k[COCO_17.index("right_ear")] = np.nan
    np.testing.assert_allclose(to_skeleton14(k, "coco_17")[J["head"]], [1, 0, 4], atol=EXACT)   # eyes
    k[COCO_17.index("left_eye")] = np.nan
    np.testing.assert_allclose(to_skeleton14(k, "coco_17")[J["head"]], [1, 1, 1], atol=EXACT)   # left ear
    k[COCO_17.index("left_ear")] = np.nan
    np.testing.assert_allclose(to_skeleton14(k, "coco_17")[J["head"]], [5, 5, 5], atol=EXACT)   # nose
    k[COCO_17.index("nose")] = np.nan
    assert np.isnan(to_skeleton14(k, "coco_17")[J["head"]]).all()
    # a missing shoulder makes the neck and that shoulder missing, nothing else
    k[COCO_17.index("left_shoulder")] = np.nan
    out = to_skeleton14(k, "coco_17")
    assert np.isnan(out[J["neck"]]).all() and np.isnan(out[J["l_shoulder"]]).all()
    np.testing.assert_allclose(out[J["r_shoulder"]], [0, 2, 0], atol=EXACT)


def test_openpose_confidence_zero_means_missing():
    rng = np.random.default_rng(1)
    k = np.column_stack([rng.uniform(0, 500, (25, 2)), rng.uniform(0.3, 0.9, 25)])
    k[BODY_25.index("Neck")] = 0.0                      # OpenPose writes (0, 0, 0) when undetected
    k[BODY_25.index("LWrist")] = 0.0
    out = to_skeleton14(k, "body_25", confidence=True)
    assert out.shape == (14, 3)
    ls, rs = k[BODY_25.index("LShoulder")], k[BODY_25.index("RShoulder")]
    np.testing.assert_allclose(out[J["neck"], :2], 0.5 * (ls[:2] + rs[:2]), atol=EXACT)
    assert out[J["neck"], 2] == min(ls[2], rs[2])
    assert np.isnan(out[J["l_wrist"], :2]).all() and out[J["l_wrist"], 2] == 0
    np.testing.assert_allclose(out[J["r_knee"]], k[BODY_25.index("RKnee")], atol=EXACT)
    # a threshold drops weak detections too
    out = to_skeleton14(k, "body_25", confidence=True, min_confidence=0.95)
    assert np.isnan(out[..., :2]).all() and (out[..., 2] == 0).all()


def test_batches_of_frames_and_cameras():
    rng = np.random.default_rng(2)
    k = rng.normal(size=(4, 7, 17, 2))
    k[1, 3, COCO_17.index("left_ear")] = np.nan
    out = to_skeleton14(k, "coco_17")
    assert out.shape == (4, 7, 14, 2)
    single = to_skeleton14(k[1, 3], "coco_17")
    np.testing.assert_allclose(out[1, 3], single, atol=EXACT)
    ears = 0.5 * (k[0, 0, COCO_17.index("left_ear")] + k[0, 0, COCO_17.index("right_ear")])
    np.testing.assert_allclose(out[0, 0, J["head"]], ears, atol=EXACT)


@pytest.mark.parametrize("args, where", [
    ((np.zeros((25, 3)), "body_99"), "fmt"),
    ((np.zeros((17, 3)), "body_25"), "keypoints"),
    ((np.zeros(17), "coco_17"), "keypoints"),
])
def test_bad_input(args, where):
    with pytest.raises(InputError) as e:
        to_skeleton14(*args)
    assert e.value.where == where


def test_body_25b_on_real_openpose_output():
    """Pose2Sim's demo: OpenPose BODY_25B JSON of a person standing in portrait images."""
    root = realdata_root() / "pose2sim_demo" / "S00_P00_SingleParticipant" / "S00_P00_T01_BalancingTrial"
    folder = root / "pose-associated" / "cam01_json"
    if not folder.is_dir():
        pytest.skip(f"real data not found at {folder}")
    frames = []
    for f in sorted(folder.glob("*.json")):
        people = json.loads(f.read_text())["people"]
        if people and "pose_keypoints_2d" in people[0]:
            frames.append(np.reshape(people[0]["pose_keypoints_2d"], (25, 3)))
    k = np.stack(frames)
    # the person leans far forward while balancing, so test distances along the body, not image rows
    out = to_skeleton14(k, "body_25b", confidence=True, min_confidence=0.2)
    hip = 0.5 * (out[:, J["l_hip"], :2] + out[:, J["r_hip"], :2])

    def dist(a, b):
        return np.linalg.norm(a - b, axis=-1)

    def mostly(x):
        return np.mean(x[np.isfinite(x)] > 0) > 0.9

    assert mostly(dist(out[:, J["head"], :2], hip) - dist(out[:, J["neck"], :2], hip))
    for s in ("l_", "r_"):
        h = out[:, J[s + "hip"], :2]
        assert mostly(dist(out[:, J[s + "ankle"], :2], h) - dist(out[:, J[s + "knee"], :2], h))
    # bones of one side have similar image lengths to the other side (left/right ids not mixed up)
    for a, b in (("l_hip", "l_knee"), ("l_knee", "l_ankle"), ("l_shoulder", "l_elbow")):
        la = dist(out[:, J[a], :2], out[:, J[b], :2])
        ra = dist(out[:, J["r" + a[1:]], :2], out[:, J["r" + b[1:]], :2])
        assert 0.6 < np.nanmedian(la / ra) < 1.6
    # left and right hips are on opposite sides of the trunk axis, consistently
    axis = out[:, J["neck"], :2] - hip
    side = np.sign(np.cross(axis, out[:, J["l_hip"], :2] - hip))
    assert abs(np.nanmean(side)) > 0.8
