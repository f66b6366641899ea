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


# --------------------------------------------------------------------------- trials of videos only, imported

#: Pixels a blob's centre may move through one or two mp4v round trips (and its rounding to whole pixels).
BLOB_TOL_PX = 1.5


def _videos_only_trial(root: Path, rig, centres: dict) -> Path:
    """``root/Trial`` as Pose2Sim's current demos: ``videos/<camera>.mp4`` and ``calibration/Calib.qca.txt``."""
    from tests.io.test_io_qualisys import qca_text

    trial = root / "Trial"
    (trial / "videos").mkdir(parents=True)
    (trial / "calibration").mkdir()
    (trial / "calibration" / "Calib.qca.txt").write_text(qca_text(rig))
    for cam in rig:
        _video(trial / "videos" / f"{cam.name}.mp4", centres[cam.name], size=cam.size)
    return trial


def _blob_centre(image: np.ndarray) -> np.ndarray:
    ys, xs = np.nonzero(image[..., 0] > 128)
    return np.array([xs.mean(), ys.mean()])


def _small_trial(tmp_path: Path, n_frames: int = 8) -> Path:
    from tests.io.conftest import random_rig

    rig = random_rig(np.random.default_rng(0), n_cams=2, size=(80, 64), names=["cam01", "cam02"])
    return _videos_only_trial(tmp_path, rig, {c.name: _path(n_frames, 5 + i) for i, c in enumerate(rig)})


def test_a_videos_only_trial_imports_with_its_keypoints_detected(tmp_path, blob_backend, capsys):
    from recipes.import_pose2sim import main
    from toolkit.io import Dataset

    trial = _small_trial(tmp_path)
    assert main([str(trial), "--out", str(tmp_path / "ds"), "--detector", "blob", "--workers", "1", "--quiet"]) == 0
    printed = capsys.readouterr().out
    assert "keypoints detected (blob: bright pixels)" in printed and "8 frames" in printed
    ds = Dataset.open(tmp_path / "ds")
    assert ds.camera_names == ["cam01", "cam02"] and ds.n_frames == 8 and ds.has_keypoints
    rep = json.loads((tmp_path / "ds" / "import.json").read_text())
    assert rep["pose_model"] == "blazepose_33" and rep["detection"]["detector"] == "blob"
    assert rep["frame_offsets"] is None and rep["detection"]["people_per_frame"]["cam02"] == {"1": 8}
    for name in ds.camera_names:
        files = sorted(ds.keypoint_dir(name).iterdir())
        assert len(files) == 8
        # links into the dataset's own detection/ folder, relative: the dataset can be moved
        assert all(f.is_symlink() and not os.path.isabs(os.readlink(f)) for f in files)
        assert files[3].resolve().parent == (tmp_path / "ds" / "detection" / name).resolve()
        x, y = json.loads(files[3].read_text())["people"][0]["pose_keypoints_2d"][48:50]
        np.testing.assert_allclose([x, y], _blob_centre(ds.frame(name, 3)), atol=BLOB_TOL_PX)


def test_sync_lines_the_cameras_up_in_the_imported_dataset(tmp_path, blob_backend):
    """Cameras that started 0, 6 and 11 frames late: after the import every frame 0 shows the same instant."""
    from dataclasses import replace

    from toolkit.cameras import Camera, Rig
    from toolkit.io import Dataset
    from toolkit.io.openpose import frame_files
    from toolkit.pipeline.trial_input import import_lines, import_trial

    size = (160, 120)
    rig = Rig(tuple(Camera.look_at(f"cam{i + 1:02d}", [4 * np.cos(a), 4 * np.sin(a), 1.5], [0, 0, 1], size=size,
                                   focal_px=120.0) for i, a in enumerate(np.linspace(0, 2 * np.pi, 3, endpoint=False))))
    rng = np.random.default_rng(0)
    T = 120
    # a point wandering in jerks (still spells, sudden steps) around (0, 0, 1), metres
    X = np.cumsum(np.where(rng.random((T, 3)) < 0.3, rng.normal(0, 0.08, (T, 3)), 0.0), axis=0).clip(-0.6, 0.6)
    X += [0, 0, 1.0]
    late = {"cam01": 0, "cam02": 6, "cam03": 11}
    trial = _videos_only_trial(tmp_path, rig, {c.name: c.project(X[late[c.name]:]) for c in rig})
    res = import_trial(trial, tmp_path / "ds", detect_config=replace(blob_backend, sync=True), log=lambda *_: None)
    assert res.report["frame_offsets"] == late
    start = max(late.values())
    assert {c["name"]: c["frames_dropped_at_start"] for c in res.report["cameras"]} == \
        {n: start - k for n, k in late.items()}
    assert res.report["n_frames"] == min(T - k - (start - k) for k in late.values()) == T - start
    lines = import_lines(res)
    assert any("cam01 11, cam02 5" in line for line in lines)
    assert any("cam02 started 6 frames late, its first 5 frames dropped" in line for line in lines)
    ds = Dataset.open(tmp_path / "ds")
    for cam in rig:
        files, nums = frame_files(ds.keypoint_dir(cam.name), "keypoints")
        assert nums.tolist() == list(range(T - start))
        for t in (0, 40):
            truth = cam.project(X[start + t])       # the same instant in every camera
            np.testing.assert_allclose(_blob_centre(ds.frame(cam.name, t)), truth, atol=BLOB_TOL_PX)
            kp = json.loads(files[t].read_text())["people"][0]["pose_keypoints_2d"]
            np.testing.assert_allclose(kp[48:50], truth, atol=BLOB_TOL_PX)


def test_sync_of_a_trial_uses_its_calibration_without_being_told(tmp_path, blob_backend):
    """detect_keypoints.py TRIAL --sync: the trial's own calibration makes it the ray-geometry solve."""
    from dataclasses import replace

    from toolkit.cameras import Camera, Rig
    from toolkit.pipeline.detect_keypoints import detect_videos

    size = (160, 120)
    rig = Rig(tuple(Camera.look_at(f"cam{i + 1:02d}", [4 * np.cos(a), 4 * np.sin(a), 1.5], [0, 0, 1], size=size,
                                   focal_px=120.0) for i, a in enumerate(np.linspace(0, 2 * np.pi, 3, endpoint=False))))
    rng = np.random.default_rng(1)
    T = 90
    X = np.cumsum(np.where(rng.random((T, 3)) < 0.3, rng.normal(0, 0.08, (T, 3)), 0.0), axis=0).clip(-0.6, 0.6)
    X += [0, 0, 1.0]
    late = {"cam01": 0, "cam02": 5, "cam03": 0}
    trial = _videos_only_trial(tmp_path, rig, {c.name: c.project(X[late[c.name]:]) for c in rig})
    lines = []
    res = detect_videos(trial, tmp_path / "kp", replace(blob_backend, sync=True), log=lines.append)
    assert res.sync.method == "rays" and res.sync.offsets == late
    assert any("the trial's calibration" in line for line in lines)


def test_free_viewpoint_input_imports_a_trial_once_and_passes_a_dataset_through(tmp_path, blob_backend):
    from toolkit.pipeline.trial_input import prepare_run_input

    trial = _small_trial(tmp_path, n_frames=8)
    out = tmp_path / "fvv"
    first = prepare_run_input(trial, out, max_frames=4, detect_config=blob_backend, log=lambda *_: None)
    assert first.dataset == out / "dataset" and first.out == out / "results"
    assert first.imported.report["n_frames"] == 4 and first.imported.report["detection"]["max_frames"] == 4
    assert "is a Pose2Sim trial: imported into" in first.lines[0]
    again = prepare_run_input(trial, out, max_frames=3, detect_config=blob_backend, log=lambda *_: None)
    assert again.imported.reused and again.imported.report["n_frames"] == 4
    more = prepare_run_input(trial, out, detect_config=blob_backend, log=lambda *_: None)
    assert not more.imported.reused and more.imported.report["n_frames"] == 8
    assert len(list((out / "dataset" / "keypoints" / "cam01").iterdir())) == 8
    # a dataset is used as it is, with the results where asked
    given = prepare_run_input(out / "dataset", tmp_path / "other")
    assert given.dataset == out / "dataset" and given.out == tmp_path / "other" and given.lines == []


def test_a_trial_without_videos_is_a_clear_error(tmp_path, blob_backend):
    from toolkit.pipeline.trial_input import import_trial, prepare_run_input

    trial = _small_trial(tmp_path)
    for v in (trial / "videos").iterdir():
        v.unlink()
    with pytest.raises(InputError, match=r"Trial.*videos/ and a calibration folder"):
        import_trial(trial, tmp_path / "ds", detect_config=blob_backend)
    with pytest.raises(InputError, match=r"Trial.*a dataset folder .* or a Pose2Sim trial"):
        prepare_run_input(trial, tmp_path / "fvv")
    # an --out holding something else than an earlier run on a trial
    trial = _small_trial(tmp_path / "b")
    (tmp_path / "busy").mkdir()
    (tmp_path / "busy" / "notes.txt").write_text("x")
    with pytest.raises(InputError, match=r"busy.*notes.txt"):
        prepare_run_input(trial, tmp_path / "busy", detect_config=blob_backend)


@pytest.mark.realdata
def test_multiperson_trial_of_videos_only_imports_with_detection(tmp_path):
    trial = REALDATA / "pose2sim_multiperson"
    if not (trial / "videos").is_dir():
        pytest.skip(f"real data not found at {trial}")
    pytest.importorskip("mediapipe")
    from toolkit.io import Dataset
    from toolkit.pipeline.trial_input import import_trial

    res = import_trial(trial, tmp_path / "ds", detect_config=DetectConfig(max_frames=5, progress=False),
                       log=lambda *_: None)
    ds = Dataset.open(tmp_path / "ds")
    assert ds.camera_names == ["cam01", "cam02", "cam03", "cam04"] and ds.n_frames == 5
    assert res.report["pose_model"] == "blazepose_33"
    for name in ds.camera_names:
        assert len(list(ds.keypoint_dir(name).glob("*.json"))) == 5
    people = res.report["detection"]["people_per_frame"]
    assert all(sum(n for k, n in h.items() if k != "0") >= 3 for h in people.values())   # somebody seen
