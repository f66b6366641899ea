"""Detection runs over videos: files written, resumed, refused, warned; synchronisation; the built-in model."""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import pytest

from toolkit.detection import BACKENDS, Detection
from toolkit.detection.sync import find_offsets, motion_signal
from toolkit.errors import InputError
from toolkit.io.video import write_video
from toolkit.pipeline.detect_keypoints import (DetectConfig, detect_videos, find_videos, read_sync,
                                               synchronise)
from toolkit.skeleton.mappings import BLAZEPOSE_33

REALDATA = Path(os.environ.get("TOOLKIT_REALDATA", Path(__file__).resolve().parents[2].parent / "shared" / "realdata"))
#: A person's keypoints around the bright blob's centre (pixels): a column of 33 points.
TEMPLATE = np.column_stack([np.zeros(33), np.linspace(-12, 12, 33)])


class BlobDetector:
    """A stand-in backend: one person wherever the image is bright, keypoints on a vertical line."""

    name, layout, model = "blob", "blazepose_33", "bright pixels"

    def __init__(self, **_):
        pass

    def detect(self, image):
        ys, xs = np.nonzero(image[..., 0] > 128)
        if len(xs) < 4:
            return []
        kp = np.column_stack([TEMPLATE + [xs.mean(), ys.mean()], np.ones(33)])
        return [Detection(keypoints=kp, score=1.0)]

    def close(self):
        pass


@pytest.fixture
def blob_backend(monkeypatch):
    monkeypatch.setitem(BACKENDS, "blob", lambda **o: BlobDetector(**o))
    return DetectConfig(detector="blob", workers=1, progress=False)


def _path(n: int, seed: int) -> np.ndarray:
    """A jerky 2D path of a blob (pixels), n frames: still spells and fast moves."""
    rng = np.random.default_rng(seed)
    speed = np.where(rng.random(n) < 0.3, rng.normal(0, 3, n), 0.0)
    return np.column_stack([40 + np.cumsum(speed).clip(-25, 25), 32 + 8 * np.sin(np.arange(n) / 7)])


def _video(path: Path, centres: np.ndarray, fps: float = 25.0, size=(80, 64)) -> Path:
    frames = []
    for cx, cy in centres:
        img = np.zeros((size[1], size[0], 3), np.uint8)
        x, y = int(round(cx)), int(round(cy))
        img[max(y - 3, 0):y + 4, max(x - 3, 0):x + 4] = 255
        frames.append(img)
    write_video(path, frames, fps)
    return path


def test_files_written_resumed_and_refused(tmp_path, blob_backend):
    videos = tmp_path / "videos"
    videos.mkdir()
    path = _path(30, 0)
    for c in ("cam01", "cam02"):
        _video(videos / f"{c}.mp4", path)
    out = tmp_path / "kp"
    result = detect_videos(tmp_path, out, blob_backend, log=lambda *_: None)
    assert result.frames_detected == 60 and result.layout == "blazepose_33"
    f = out / "cam01" / "cam01_000000000007_keypoints.json"
    people = json.loads(f.read_text())["people"]
    assert len(people) == 1 and len(people[0]["pose_keypoints_2d"]) == 33 * 3
    x, y = people[0]["pose_keypoints_2d"][48:50]   # keypoint 16 sits at the blob's centre
    assert abs(x - path[7, 0]) < 1.5 and abs(y - path[7, 1]) < 1.5
    doc = json.loads((out / "detection.json").read_text())
    assert doc["keypoint_names"] == list(BLAZEPOSE_33) and doc["cameras"]["cam02"]["people_per_frame"] == {"1": 30}
    # an interrupted run: frames lost are redone, the others kept
    for k in (3, 4, 29):
        (out / "cam02" / f"cam02_{k:012d}_keypoints.json").unlink()
    again = detect_videos(tmp_path, out, blob_backend, log=lambda *_: None)
    assert again.cameras["cam02"]["frames_detected_now"] == 3 and again.cameras["cam01"]["frames_detected_now"] == 0
    # other options into the same folder: refused, naming the file
    from dataclasses import replace
    with pytest.raises(InputError, match="detection.json"):
        detect_videos(tmp_path, out, replace(blob_backend, num_poses=2), log=lambda *_: None)


def test_the_keypoint_readers_take_the_folder(tmp_path, blob_backend):
    from toolkit.io.keypoint_files import camera_sources
    from toolkit.io.keypoint_formats import read_keypoints

    _video(tmp_path / "a.mp4", _path(12, 1))
    _video(tmp_path / "b.mp4", _path(12, 2))
    detect_videos([tmp_path / "a.mp4", tmp_path / "b.mp4"], tmp_path / "kp", blob_backend, log=lambda *_: None)
    data = read_keypoints(camera_sources(tmp_path / "kp"))
    assert data.format.fmt == "blazepose_33" and data.keypoints.shape == (2, 12, 33, 3)


def test_sync_finds_late_starts_and_keeps_a_synchronised_rig_at_zero(tmp_path, blob_backend):
    path = _path(120, 3)
    late = {"cam01": 0, "cam02": 6, "cam03": 11}
    (tmp_path / "v").mkdir()
    (tmp_path / "s").mkdir()
    for name, k in late.items():
        # the same motion, seen a little shifted, starting k frames late
        _video(tmp_path / "v" / f"{name}.mp4", path[k:] + [2.0 * (k > 0), 0.0])
    out = tmp_path / "kp"
    result = detect_videos(tmp_path / "v", out, DetectConfig(detector="blob", workers=1, progress=False, sync=True),
                           log=lambda *_: None)
    assert result.sync.offsets == late
    assert read_sync(out) == late
    # a rig in sync
    for name in late:
        _video(tmp_path / "s" / f"{name}.mp4", path)
    detect_videos(tmp_path / "s", tmp_path / "kp2", blob_backend, log=lambda *_: None)
    assert synchronise(tmp_path / "kp2").offsets == {n: 0 for n in late}


def test_sync_offsets_shift_the_frames_read(tmp_path, blob_backend):
    from toolkit.io.keypoint_files import camera_sources
    from toolkit.io.keypoint_formats import read_keypoints
    from toolkit.pipeline.keypoint_session import frame_offsets

    path = _path(60, 4)
    (tmp_path / "v").mkdir()
    _video(tmp_path / "v" / "cam01.mp4", path)
    _video(tmp_path / "v" / "cam02.mp4", path[5:])
    detect_videos(tmp_path / "v", tmp_path / "kp", DetectConfig(detector="blob", workers=1, progress=False,
                                                                sync=True), log=lambda *_: None)
    sources = camera_sources(tmp_path / "kp")
    data = read_keypoints(sources, frame_offsets=frame_offsets(tmp_path / "kp", sources))
    # after the shift, both cameras see the blob at the same place at the same frame
    both = np.isfinite(data.keypoints[:, :, 16, 0]).all(axis=0)
    assert both.sum() == 55
    assert np.abs(data.keypoints[0, both, 16, :2] - data.keypoints[1, both, 16, :2]).max() < 1.5


def test_find_offsets_on_signals():
    rng = np.random.default_rng(0)
    base = np.abs(rng.normal(size=200)) * (rng.random(200) < 0.3)
    sig = {"a": base[10:150], "b": base[:140] * 2.0, "c": base[14:154] + 0.01}
    res = find_offsets(sig, max_offset=30)
    assert res.offsets == {"a": 10, "b": 0, "c": 14} and all(res.trusted.values())
    with pytest.raises(InputError, match="at least two cameras"):
        find_offsets({"a": base})


def test_motion_signal_is_nan_without_people():
    kp = np.column_stack([TEMPLATE + [10, 10], np.ones(33)])
    s = motion_signal([[kp], [], [kp + [1, 0, 0]], [kp + [2, 0, 0]]])
    assert np.isnan(s[0]) and np.isnan(s[1]) and s[2] > 0 and np.isnan(s[3])


def test_bad_input_is_named(tmp_path, blob_backend):
    bad = tmp_path / "broken.mp4"
    bad.write_text("not a video")
    with pytest.raises(InputError, match="broken.mp4"):
        detect_videos([bad], tmp_path / "kp", blob_backend, log=lambda *_: None)
    (tmp_path / "nothing_here").mkdir()
    with pytest.raises(InputError, match="video files"):
        find_videos(tmp_path / "nothing_here")
    with pytest.raises(InputError, match="detector"):
        DetectConfig(detector="openpifpaf")


def test_different_rates_and_nobody_are_warned_with_files_written(tmp_path, blob_backend):
    (tmp_path / "v").mkdir()
    empty = np.zeros((10, 2)) - 100      # the blob off the image: nobody
    _video(tmp_path / "v" / "cam01.mp4", empty, fps=25.0)
    _video(tmp_path / "v" / "cam02.mp4", empty, fps=30.0)
    lines = []
    result = detect_videos(tmp_path / "v", tmp_path / "kp", blob_backend, log=lines.append)
    text = " ".join(result.warnings)
    assert "different frame rates" in text and "nobody found in any camera" in text
    assert any("different frame rates" in x for x in lines)
    assert len(list((tmp_path / "kp" / "cam02").glob("*.json"))) == 10


def test_builtin_model_loads_offline_and_finds_nobody_in_a_blank_image(tmp_path):
    pytest.importorskip("mediapipe")
    from toolkit.detection import make_detector

    det = make_detector("mediapipe", cache=tmp_path)
    try:
        assert det.detect(np.full((240, 320, 3), 127, np.uint8)) == []
    finally:
        det.close()
    assert list(tmp_path.glob("pose_landmarker_full-*.task"))


def test_rtmlib_without_model_files_is_a_clear_error():
    pytest.importorskip("rtmlib", reason="rtmlib not installed (an optional backend)")
    from toolkit.detection import make_detector

    with pytest.raises(InputError, match="ONNX"):
        make_detector("rtmlib")


@pytest.mark.realdata
def test_builtin_model_finds_both_participants():
    video = REALDATA / "pose2sim_multiperson" / "videos" / "cam01.mp4"
    if not video.is_file():
        pytest.skip(f"real data not found at {video}")
    pytest.importorskip("mediapipe")
    from toolkit.detection import make_detector
    from toolkit.io import VideoReader

    with VideoReader(video) as r:
        image = r.read(30)
    det = make_detector("mediapipe")
    try:
        people = det.detect(image)
    finally:
        det.close()
    assert len(people) >= 2
    hips = sorted(float(p.keypoints[23, 0]) for p in people[:2])   # two people apart in the image
    assert hips[1] - hips[0] > 50


def test_a_trial_with_videos_and_a_qualisys_calibration_enters_pose_from_keypoints(tmp_path, blob_backend):
    """Pose2Sim's current layout: videos/ and calibration/Calib.qca.txt in the trial, no keypoints."""
    from tests.io.conftest import random_rig
    from tests.io.test_io_qualisys import qca_text
    from toolkit.pipeline.pose_from_keypoints import PoseFromKeypointsConfig, run

    trial = tmp_path / "Trial"
    (trial / "videos").mkdir(parents=True)
    (trial / "calibration").mkdir()
    rig = random_rig(np.random.default_rng(0), n_cams=2, size=(80, 64), names=["cam01", "cam02"])
    (trial / "calibration" / "Calib.qca.txt").write_text(qca_text(rig))
    for c in ("cam01", "cam02"):
        _video(trial / "videos" / f"{c}.mp4", _path(8, 5))
    config = PoseFromKeypointsConfig(detection=blob_backend, recording=False, export=(), progress=False)
    result = run(config, dataset=trial, out=tmp_path / "out", log=lambda *_: None)
    assert (tmp_path / "out" / "keypoints" / "detection.json").is_file()
    assert len(list((tmp_path / "out" / "keypoints" / "cam02").glob("*.json"))) == 8
    assert (tmp_path / "out" / "poses3d.npz").is_file() and result.frames == 8
    data = np.load(tmp_path / "out" / "poses3d.npz")
    assert float(data["frame_rate"]) == 25.0        # the videos' rate, read from detection.json


def test_geometric_sync_finds_a_late_camera_and_keeps_a_synchronised_one_at_zero():
    from tests.io.conftest import random_rig
    from toolkit.detection.sync import find_offsets_geometric

    rng = np.random.default_rng(2)
    rig = random_rig(rng, n_cams=3, size=(640, 480), dist_lengths=(4,))
    body = rng.normal(0, 0.25, (33, 3)) + [0, 0, 1.0]
    # limbs swinging: every keypoint on its own slow sinusoid
    phase, amp = rng.uniform(0, 6, (33, 1)), rng.uniform(0.05, 0.3, (33, 3))
    T = 90
    X = body + np.cumsum(rng.normal(0, 0.03, (T, 33, 3)), axis=0)   # limbs wandering, not periodic
    late = {rig.cameras[0].name: 0, rig.cameras[1].name: 5, rig.cameras[2].name: 0}
    people = {}
    for cam in rig.cameras:
        k = late[cam.name]
        uv = cam.project(X[k:]) + rng.normal(0, 0.5, (T - k, 33, 2))
        people[cam.name] = [[np.column_stack([u, np.ones(33)])] for u in uv]
    res = find_offsets_geometric(people, {c.name: c for c in rig.cameras}, max_offset=15)
    assert res.offsets == late, (res.trusted, res.peaks, res.second)
    assert all(res.trusted.values())
