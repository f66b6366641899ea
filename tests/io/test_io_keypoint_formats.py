"""Keypoint files of the common detectors (toolkit.io.keypoint_formats): layouts, format detection, bad input."""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import pytest

from toolkit.errors import InputError
from toolkit.io.keypoint_formats import (body25_evidence, camera_sources, detect_format, match_cameras,
                                         read_camera_detections, read_keypoints)
from toolkit.skeleton import JOINTS_14
from toolkit.skeleton.mappings import KEYPOINTS, to_skeleton14

REPO_ROOT = Path(__file__).resolve().parents[2]
#: Pixel jitter of the hand-made figures (so no two keypoints coincide exactly).
JITTER_PX = 0.5
#: A standing person facing the camera, pixels (y down; the person's left at +x).
FIGURE = {
    "HeadTop": (100, 20), "Head": (100, 22), "Nose": (100, 40), "LEye": (105, 35), "REye": (95, 35),
    "LEar": (110, 38), "REar": (90, 38), "UpperNeck": (100, 55), "Neck": (100, 70),
    "LShoulder": (125, 70), "RShoulder": (75, 70), "LElbow": (130, 110), "RElbow": (70, 110),
    "LWrist": (132, 150), "RWrist": (68, 150), "MidHip": (100, 150), "Hip": (100, 150),
    "LHip": (115, 150), "RHip": (85, 150), "LKnee": (116, 210), "RKnee": (84, 210),
    "LAnkle": (117, 270), "RAnkle": (83, 270), "LHeel": (115, 280), "RHeel": (85, 280),
    "LBigToe": (125, 285), "RBigToe": (75, 285), "LSmallToe": (130, 283), "RSmallToe": (70, 283)}


def _norm(name: str) -> str:
    return "".join(ch for ch in name.lower().replace("left", "l").replace("right", "r") if ch.isalnum())


NORM_FIGURE = {_norm(k): v for k, v in FIGURE.items()}


def figure(fmt: str, shift=(0.0, 0.0), conf=0.9, rng=None) -> np.ndarray:
    """(K, 3) keypoints of FIGURE in ``fmt`` (face and hand points at the nose)."""
    rng = rng or np.random.default_rng(0)
    out = []
    for name in KEYPOINTS[fmt]:
        xy = NORM_FIGURE.get(_norm(name), FIGURE["Nose"])
        out.append([xy[0] + shift[0], xy[1] + shift[1], conf])
    out = np.array(out, float)
    out[:, :2] += rng.normal(0, JITTER_PX, (len(out), 2))
    return out


def _dump(path: Path, data):
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(data))


def write_openpose(folder: Path, frames: dict[int, list[np.ndarray]]):
    for n, people in frames.items():
        _dump(folder / f"cam.{n:04d}.json",
              {"version": 1.3, "people": [{"person_id": [-1], "pose_keypoints_2d": p.ravel().tolist()}
                                          for p in people]})


def _instance(p: np.ndarray) -> dict:
    return {"keypoints": p[:, :2].tolist(), "keypoint_scores": p[:, 2].tolist(), "bbox": [[0, 0, 200, 300]],
            "bbox_score": 0.99}


def _expected14(fmt, p):
    return to_skeleton14(p[None], fmt, confidence=True)[0]


@pytest.mark.parametrize("fmt", ["body_25", "body_25b", "coco_18", "coco_17", "halpe_26", "coco_133", "blazepose_33"])
def test_openpose_layout_every_format_detected(tmp_path, fmt):
    rng = np.random.default_rng(1)
    cams = []
    for c in range(2):
        write_openpose(tmp_path / f"cam{c + 1:02d}_json",
                       {t: [figure(fmt, (10 * t, 0), rng=rng)] for t in range(6)})
        cams.append(read_camera_detections(tmp_path / f"cam{c + 1:02d}_json"))
    choice = detect_format(cams)
    assert choice.fmt == fmt
    got = read_keypoints(camera_sources(tmp_path))
    assert got.format.fmt == fmt and got.keypoints.shape == (2, 6, len(KEYPOINTS[fmt]), 3)
    assert got.frames.tolist() == list(range(6)) and not got.missing.any() and not got.empty.any()
    np.testing.assert_array_equal(got.keypoints[0, 0], cams[0].people[0][0])
    # every limb joint of the 14 lands where the figure has it: no left/right or index mix-up
    j14 = to_skeleton14(got.keypoints, fmt, confidence=True)
    for j, name in enumerate(JOINTS_14):
        if name in ("head", "neck"):
            continue
        side, part = name.split("_")
        expected = FIGURE[side.upper() + part.capitalize()]
        assert np.all(np.abs(j14[0, 0, j, :2] - expected) < 4 * JITTER_PX), name
    head = 0.5 * (np.array(FIGURE["LEar"]) + np.array(FIGURE["REar"]))
    assert np.all(np.abs(j14[0, 0, JOINTS_14.index("head"), :2] - head) < 4 * JITTER_PX)


def test_body25_and_body25b_told_apart_on_the_same_figure(tmp_path):
    rng = np.random.default_rng(2)
    cams = {}
    for fmt in ("body_25", "body_25b"):
        write_openpose(tmp_path / fmt / "cam01", {t: [figure(fmt, rng=rng)] for t in range(6)})
        cams[fmt] = [read_camera_detections(tmp_path / fmt / "cam01")]
    assert np.all(body25_evidence(cams["body_25"]) < -1.0)
    assert np.all(body25_evidence(cams["body_25b"]) > 1.0)
    # declared wrongly: the layout contradicts it, the error says so
    with pytest.raises(InputError, match="laid out like body_25b"):
        detect_format(cams["body_25b"], "body_25")


def test_ambiguous_25_keypoints_is_an_error_naming_the_folder(tmp_path):
    p = figure("body_25")
    p[[0, 1, 8, 15, 16, 17, 18, 19, 20, 21, 22, 23, 24], :] = 0.0      # limbs only: nothing tells the layouts apart
    write_openpose(tmp_path / "cam01_json", {t: [p] for t in range(6)})
    with pytest.raises(InputError, match="BODY_25 or BODY_25B") as e:
        read_keypoints([tmp_path / "cam01_json"])
    assert "cam01_json" in str(e.value) and "0 detections" in str(e.value)
    assert read_keypoints([tmp_path / "cam01_json"], "body_25").format.reason == "declared by --format"


def test_unknown_count_and_mixed_counts_name_the_file(tmp_path):
    write_openpose(tmp_path / "a", {0: [figure("coco_17")[:15]]})
    with pytest.raises(InputError, match="15 keypoints per person") as e:
        read_keypoints([tmp_path / "a"])
    assert "known format" in str(e.value)
    write_openpose(tmp_path / "b", {0: [figure("coco_17")], 1: [figure("coco_17")], 2: [figure("coco_17")[:12]]})
    with pytest.raises(InputError, match="12 keypoints") as e:
        read_keypoints([tmp_path / "b"])
    assert "cam.0002.json" in str(e.value) and "17 keypoints per person" in str(e.value)
    # a person with fewer keypoints than the declared format
    with pytest.raises(InputError, match="17 keypoints per person for coco_17") as e:
        read_keypoints([tmp_path / "a"], "coco_17")
    assert "cam.0000.json" in str(e.value)


def test_mmpose_per_frame_files(tmp_path):
    for t in range(3):
        _dump(tmp_path / "cam01" / f"frame_{t:06d}.json", [_instance(figure("coco_17", (t, 0)))])
    _dump(tmp_path / "cam01" / "frame_000003.json", [])                 # nobody
    det = read_camera_detections(tmp_path / "cam01")
    assert det.layout == "mmpose_frame" and det.frames.tolist() == [0, 1, 2, 3]
    got = read_keypoints([tmp_path / "cam01"])
    assert got.format.fmt == "coco_17" and got.empty[0].tolist() == [False, False, False, True]
    assert np.isnan(got.keypoints[0, 3, :, :2]).all()


def test_mmpose_video_predictions_and_demo_file_with_names(tmp_path):
    frames = [{"frame_id": t, "instances": [_instance(figure("halpe_26", (t, 0))),
                                            _instance(figure("halpe_26", (300, 0), conf=0.3))]} for t in range(4)]
    _dump(tmp_path / "cam01.json", frames)
    det = read_camera_detections(tmp_path / "cam01.json")
    assert det.layout == "mmpose_video" and det.people[0].shape == (2, 26, 3)
    got = read_keypoints([tmp_path / "cam01.json"])
    assert got.format.fmt == "halpe_26"
    assert got.keypoints[0, 1, 0, 0] < 150                             # the more confident person
    # the MMPose demo's file: keypoint names in meta_info decide (COCO-17 names, snake case)
    names = {str(i): n for i, n in enumerate(KEYPOINTS["coco_17"])}
    _dump(tmp_path / "demo.json", {"meta_info": {"dataset_name": "coco", "keypoint_id2name": names},
                                   "instance_info": [{"frame_id": t + 1, "instances": [_instance(figure("coco_17"))]}
                                                     for t in range(3)]})
    got = read_keypoints([tmp_path / "demo.json"])
    assert got.format.fmt == "coco_17" and "names" in got.format.reason and got.frames.tolist() == [1, 2, 3]
    # names that contradict the format (left and right swapped): never a silent wrong mapping
    swapped = {k: v.replace("left", "tmp").replace("right", "left").replace("tmp", "right") for k, v in names.items()}
    _dump(tmp_path / "demo.json", {"meta_info": {"keypoint_id2name": swapped},
                                   "instance_info": [{"frame_id": 0, "instances": [_instance(figure("coco_17"))]}]})
    for declared in (None, "coco_17"):
        with pytest.raises(InputError, match="keypoint names") as e:
            read_keypoints([tmp_path / "demo.json"], declared)
        assert "demo.json" in str(e.value)


def test_coco_results_and_annotations(tmp_path):
    res = [{"image_id": t, "category_id": 1, "keypoints": figure("coco_17", (t, 0)).ravel().tolist(), "score": 0.9}
           for t in (0, 1, 3)]
    _dump(tmp_path / "cam01.json", res)
    got = read_keypoints([tmp_path / "cam01.json"])
    assert got.format.fmt == "coco_17" and got.frames.tolist() == [0, 1, 3]
    kp = figure("coco_17")
    kp[:, 2] = 2.0
    kp[4] = [0, 0, 0]                                                    # not labelled
    ann = {"images": [{"id": 7, "file_name": "cam02_000010.jpg"}, {"id": 8, "file_name": "cam02_000011.jpg"}],
           "annotations": [{"image_id": 7, "keypoints": kp.ravel().tolist(), "num_keypoints": 16}],
           "categories": [{"id": 1, "name": "person", "keypoints": list(KEYPOINTS["coco_17"])}]}
    _dump(tmp_path / "cam02.json", ann)
    det = read_camera_detections(tmp_path / "cam02.json")
    assert det.layout == "coco_annotations" and det.frames.tolist() == [10, 11] and len(det.people[1]) == 0
    assert det.people[0][0, 0, 2] == 1.0 and det.people[0][0, 4, 2] == 0.0 and np.isnan(det.people[0][0, 4, 0])


def test_missing_keypoints_nan_confidence_and_no_people(tmp_path):
    p = figure("coco_17")
    p[3, 2] = np.nan                                                     # NaN confidence: missing
    p[5, 0] = np.nan                                                     # NaN coordinate: missing
    folder = tmp_path / "cam01"
    _dump(folder / "f.0000.json", {"people": [{"pose_keypoints_2d": [None if np.isnan(v) else v for v in p.ravel()]}]})
    write_openpose(folder, {1: []})                                      # no people
    _dump(folder / "f.0002.json", {"people": [{}]})                      # Pose2Sim: nobody associated
    got = read_keypoints([folder], "coco_17")
    assert got.keypoints.shape == (1, 3, 17, 3) and got.empty[0].tolist() == [False, True, True]
    k = got.keypoints[0, 0]
    assert np.isnan(k[[3, 5], :2]).all() and (k[[3, 5], 2] == 0).all() and (k[[0, 4, 6], 2] == 0.9).all()


def test_negative_confidence_is_an_error_naming_the_file(tmp_path):
    p = figure("coco_17")
    p[6, 2] = -0.5
    write_openpose(tmp_path / "cam01", {0: [figure("coco_17")], 1: [p]})
    with pytest.raises(InputError, match="confidences >= 0") as e:
        read_camera_detections(tmp_path / "cam01")
    assert "cam.0001.json" in str(e.value) and "-0.5 at keypoint 6" in str(e.value)


def test_frames_missing_in_one_camera_are_marked(tmp_path):
    write_openpose(tmp_path / "cam01", {t: [figure("coco_17")] for t in range(5)})
    write_openpose(tmp_path / "cam02", {t: [figure("coco_17")] for t in (0, 1, 4)})
    got = read_keypoints(camera_sources(tmp_path))
    assert got.frames.tolist() == [0, 1, 2, 3, 4]
    assert got.missing.tolist() == [[False] * 5, [False, False, True, True, False]]
    assert np.isnan(got.keypoints[1, 2:4, :, :2]).all() and (got.keypoints[1, 2:4, :, 2] == 0).all()
    got = read_keypoints(camera_sources(tmp_path), max_frames=2)
    assert got.keypoints.shape == (2, 2, 17, 3)


def test_layout_errors(tmp_path):
    _dump(tmp_path / "seq" / "cam01" / "all.json", [{"frame_id": 0, "instances": []}])
    with pytest.raises(InputError, match="whole-sequence"):
        read_camera_detections(tmp_path / "seq" / "cam01")
    _dump(tmp_path / "frame.json", {"people": []})
    with pytest.raises(InputError, match="per-frame file"):
        read_camera_detections(tmp_path / "frame.json")
    _dump(tmp_path / "odd" / "x.json", {"something": 1})
    with pytest.raises(InputError, match="x.json"):
        read_camera_detections(tmp_path / "odd")
    _dump(tmp_path / "mm" / "x.json", [{"keypoints": [[1, 2]] * 17}])
    with pytest.raises(InputError, match="keypoint_scores"):
        read_camera_detections(tmp_path / "mm")
    with pytest.raises(InputError, match="no such path"):
        read_camera_detections(tmp_path / "nope")
    with pytest.raises(InputError, match="no such folder"):
        camera_sources(tmp_path / "nope")
    (tmp_path / "empty").mkdir()
    with pytest.raises(InputError, match="neither sub-folders nor JSON"):
        camera_sources(tmp_path / "empty")


def test_camera_matching():
    cams = ["cam_01", "cam_02", "cam_03"]
    src = [Path("cam03_json"), Path("cam01_json"), Path("cam02_json")]
    assert match_cameras(cams, src, "kp") == ([1, 2, 0], "by name")
    src = [Path("video_3.json"), Path("video_1.json"), Path("video_2.json")]
    assert match_cameras(cams, src, "kp") == ([1, 2, 0], "by number")
    assert match_cameras(["left", "right"], [Path("a"), Path("b")], "kp") == ([0, 1], "by order")
    # folders that do not match the calibration: named in the error
    with pytest.raises(InputError) as e:
        match_cameras(cams, [Path("cam01_json"), Path("cam02_json"), Path("cam05_json")], "kp")
    assert "cam_03" in str(e.value) and "cam05_json" in str(e.value)
    with pytest.raises(InputError) as e:
        match_cameras(cams, [Path("cam01_json"), Path("cam02_json")], "kp")
    assert "cam_03" in str(e.value) and "2:" in str(e.value)
    assert match_cameras(["cam1", "cam10"], [Path("cam10"), Path("cam1")], "kp") == ([1, 0], "by name")


def _demo_trial():
    root = Path(os.environ.get("TOOLKIT_REALDATA", REPO_ROOT.parent / "shared" / "realdata")) / "pose2sim_demo"
    trial = root / "S00_P00_SingleParticipant" / "S00_P00_T01_BalancingTrial"
    if not trial.is_dir():
        pytest.skip(f"real data not found at {root}")
    return trial


@pytest.mark.realdata
def test_pose2sim_demo_detected_as_body25b_and_not_as_body25():
    trial = _demo_trial()
    got = read_keypoints(camera_sources(trial / "pose"), max_frames=20)
    assert got.format.fmt == "body_25b" and got.keypoints.shape == (4, 20, 25, 3)
    # the same detections rewritten as BODY_25 (neck and mid-hip added) read as BODY_25
    b25, b25b = KEYPOINTS["body_25"], KEYPOINTS["body_25b"]
    kp = np.full(got.keypoints.shape, np.nan)
    kp[..., 2] = 0
    for i, n in enumerate(b25):
        if n in b25b:
            kp[..., i, :] = got.keypoints[..., b25b.index(n), :]
    for i, (a, b) in ((1, ("LShoulder", "RShoulder")), (8, ("LHip", "RHip"))):
        kp[..., i, :2] = 0.5 * (got.keypoints[..., b25b.index(a), :2] + got.keypoints[..., b25b.index(b), :2])
        kp[..., i, 2] = np.minimum(got.keypoints[..., b25b.index(a), 2], got.keypoints[..., b25b.index(b), 2])
    from toolkit.io.keypoint_formats import CameraDetections
    cams = [CameraDetections(Path(f"c{c}"), "openpose", ("x",) * 20, got.frames, tuple(kp[c, :, None]))
            for c in range(4)]
    assert detect_format(cams).fmt == "body_25"


def test_openpose_reader_rejects_negative_confidence_too(tmp_path):
    from toolkit.io.openpose import read_openpose_json

    p = figure("body_25b")
    p[3, 2] = -1.0
    write_openpose(tmp_path / "cam01", {0: [p]})
    with pytest.raises(InputError, match="confidences >= 0") as e:
        read_openpose_json(tmp_path / "cam01" / "cam.0000.json", 25)
    assert "cam.0000.json" in str(e.value) and "keypoint 3" in str(e.value)
