"""Importing a Pose2Sim trial into the dataset layout (toolkit.io.pose2sim_import)."""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest

from tests.io.pose2sim_trial import VIDEO_SIZE, make_trial, tiny_rig
from toolkit.errors import InputError
from toolkit.io import Dataset, read_calibration
from toolkit.io.pose2sim_import import PAD_TOLERANCE_PX, fit_camera_to_video, import_pose2sim_trial

#: Calibrations written as TOML read back to within this (repr floats; Rodrigues round trip).
CALIB_TOL = 1e-12
#: Grey levels an mp4v round trip (two for a re-encoded video) may shift a flat frame; frames differ by 25.
GREY_TOL = 8


def test_import_links_videos_keypoints_and_the_calibration(tmp_path):
    trial = make_trial(tmp_path, n_frames=4)
    res = import_pose2sim_trial(trial, tmp_path / "ds")
    assert res.n_frames == 4 and res.messages == []
    ds = Dataset.open(tmp_path / "ds")
    assert ds.camera_names == ["cam_01", "cam_02", "cam_03"] and ds.n_frames == 4
    for cam, ref in zip(ds.rig, tiny_rig(3)):
        np.testing.assert_allclose(cam.K, ref.K, atol=CALIB_TOL)
        np.testing.assert_allclose(cam.cam_from_world, ref.cam_from_world, atol=CALIB_TOL)
    assert ds.has_keypoints
    for c, name in enumerate(ds.camera_names):
        assert ds.video_path(name).is_symlink()
        assert ds.video_path(name).resolve() == (trial / "videos" / f"cam{c + 1:02d}.mp4").resolve()
        files = sorted(p.name for p in ds.keypoint_dir(name).iterdir())
        assert files == [f"cam{c + 1:02d}.{t:04d}.json" for t in range(4)]  # names kept
        assert ds.frame(name, 2)[0, 0, 0] == pytest.approx(40 * c + 50, abs=GREY_TOL)  # the camera's own video
    rep = json.loads((tmp_path / "ds" / "import.json").read_text())
    assert rep["videos_matched"] == "by name" and rep["keypoints_matched"] == "by name"
    assert rep["n_frames"] == 4 and rep["files"] == "linked" and rep["keypoints"].endswith("pose")
    assert [c["video_size"] for c in rep["cameras"]] == [list(VIDEO_SIZE)] * 3


def test_copy_and_pose_choice_and_given_calibration(tmp_path):
    trial = make_trial(tmp_path, pose_folders=("pose", "pose-associated"))
    other = tmp_path / "other.toml"
    shutil.copy(next((tmp_path / "Session" / "S00_Calibration").glob("*.toml")), other)
    res = import_pose2sim_trial(trial, tmp_path / "ds", calibration=other, pose="pose", copy=True)
    assert res.report["calibration"] == str(other.resolve()) and res.report["keypoints"].endswith("pose")
    ds = Dataset.open(tmp_path / "ds")
    assert not ds.video_path("cam_01").is_symlink()
    assert not any(p.is_symlink() for p in ds.keypoint_dir("cam_02").iterdir())
    res = import_pose2sim_trial(trial, tmp_path / "ds2")
    assert res.report["keypoints"].endswith("pose-associated")  # Pose2Sim's own preference


def test_padded_video_keeps_the_principal_point_and_takes_the_video_size(tmp_path):
    w, h = VIDEO_SIZE
    trial = make_trial(tmp_path, calib_size=(w + 8, h))
    res = import_pose2sim_trial(trial, tmp_path / "ds")
    assert len(res.messages) == 3 and "kept K" in res.messages[0] and f"{w + 8}x{h}" in res.messages[0]
    ds = Dataset.open(tmp_path / "ds")  # the default size check passes
    for cam, ref in zip(ds.rig, tiny_rig(3, (w + 8, h))):
        assert cam.size == VIDEO_SIZE
        np.testing.assert_allclose(cam.K, ref.K, atol=CALIB_TOL)


def test_resized_video_scales_the_camera(tmp_path):
    w, h = VIDEO_SIZE
    trial = make_trial(tmp_path, calib_size=(2 * w, 2 * h))
    res = import_pose2sim_trial(trial, tmp_path / "ds")
    assert all("resized by 0.5" in m for m in res.messages)
    cam, ref = read_calibration(tmp_path / "ds" / "calibration.toml")[0], tiny_rig(3, (2 * w, 2 * h))[0]
    assert cam.size == VIDEO_SIZE
    np.testing.assert_allclose(cam.K, ref.scaled(0.5).K, atol=CALIB_TOL)


def test_size_that_is_neither_padding_nor_resizing_is_an_error(tmp_path):
    cam = tiny_rig(1)[0]
    with pytest.raises(InputError, match="cam_01"):
        fit_camera_to_video(cam, (VIDEO_SIZE[0] + PAD_TOLERANCE_PX + 2, VIDEO_SIZE[1]), "v.mp4")
    trial = make_trial(tmp_path, video_size=(64, 80))
    with pytest.raises(InputError, match=r"cam01\.mp4.*64x80"):
        import_pose2sim_trial(trial, tmp_path / "ds")


def test_frame_counts_are_trimmed_to_the_common_length(tmp_path):
    trial = make_trial(tmp_path, n_frames=[5, 4, 5])
    res = import_pose2sim_trial(trial, tmp_path / "ds")
    assert res.n_frames == 4
    assert any("trimmed to the common length 4" in m and "cam01.mp4: 5" in m for m in res.messages)
    ds = Dataset.open(tmp_path / "ds")
    assert ds.n_frames == 4
    assert not ds.video_path("cam_01").is_symlink()  # re-encoded to its first 4 frames
    assert ds.video_path("cam_02").is_symlink()
    assert ds.frame("cam_03", 3)[0, 0, 0] == pytest.approx(80 + 75, abs=GREY_TOL)
    assert len(list(ds.keypoint_dir("cam_01").iterdir())) == 4
    assert res.report["cameras"][0]["keypoint_files_left_out"] == 1


def test_missing_calibration_is_an_error(tmp_path):
    trial = make_trial(tmp_path, with_calibration=False)
    with pytest.raises(InputError, match="calibration"):
        import_pose2sim_trial(trial, tmp_path / "ds")
    assert not (tmp_path / "ds").exists()


def test_fewer_videos_than_cameras_is_an_error(tmp_path):
    trial = make_trial(tmp_path)
    (trial / "videos" / "cam03.mp4").unlink()
    with pytest.raises(InputError, match=r"fewer videos: 2"):
        import_pose2sim_trial(trial, tmp_path / "ds")


def test_pose_folders_that_match_no_camera_are_an_error(tmp_path):
    trial = make_trial(tmp_path, pose_names=["front_json", "side_json", "back_json"])
    with pytest.raises(InputError, match=r"match none.*front_json"):
        import_pose2sim_trial(trial, tmp_path / "ds")
    trial = make_trial(tmp_path / "b", pose_names=["cam01_json", "cam02_json", "cam07_json"])
    with pytest.raises(InputError, match="cam07_json"):
        import_pose2sim_trial(trial, tmp_path / "ds")


def test_pose_folders_named_after_the_videos_are_matched_through_them(tmp_path):
    names = ["front", "side", "back"]
    trial = make_trial(tmp_path, video_names=[f"{n}.mp4" for n in names], pose_names=[f"{n}_json" for n in names])
    res = import_pose2sim_trial(trial, tmp_path / "ds")
    assert res.report["videos_matched"] == "by order"
    assert any("videos matched to the cameras by sorted order" in m for m in res.messages)
    # sorted order: back, front, side -> cam_01, cam_02, cam_03, and the keypoints follow their videos
    assert [c["keypoints"].rsplit("/", 1)[1] for c in res.report["cameras"]] == ["back_json", "front_json",
                                                                                  "side_json"]


def test_non_empty_output_is_refused(tmp_path):
    trial = make_trial(tmp_path)
    (tmp_path / "ds").mkdir()
    (tmp_path / "ds" / "x.txt").write_text("x")
    with pytest.raises(InputError, match="empty"):
        import_pose2sim_trial(trial, tmp_path / "ds")
    import_pose2sim_trial(trial, tmp_path / "ds", overwrite=True)


def test_dataset_rejects_keypoint_and_mask_folders_of_unknown_cameras(tmp_path):
    trial = make_trial(tmp_path)
    import_pose2sim_trial(trial, tmp_path / "ds")
    ds = Dataset.open(tmp_path / "ds")
    assert not ds.has_masks and ds.mask("cam_01", 0) is None
    from toolkit.io import atomic_write_png
    m = np.zeros(VIDEO_SIZE[::-1], np.uint8)
    m[10:20, 5:9] = 255
    atomic_write_png(tmp_path / "ds" / "masks" / "cam_02" / "000001.png", m)
    ds = Dataset.open(tmp_path / "ds")
    assert ds.has_masks and ds.mask("cam_02", 1).sum() == 40 and ds.mask("cam_02", 0) is None
    atomic_write_png(tmp_path / "ds" / "masks" / "cam_02" / "000009.png", m)
    with pytest.raises(InputError, match="000009.png"):
        Dataset.open(tmp_path / "ds")
    (tmp_path / "ds" / "masks" / "cam_02" / "000009.png").unlink()
    (tmp_path / "ds" / "keypoints" / "cam_09").mkdir()
    with pytest.raises(InputError, match="cam_09"):
        Dataset.open(tmp_path / "ds")


@pytest.mark.realdata
def test_demo_balancing_trial_imports_and_opens(pose2sim_demo, tmp_path):
    trial = pose2sim_demo / "S00_P00_SingleParticipant" / "S00_P00_T01_BalancingTrial"
    res = import_pose2sim_trial(trial, tmp_path / "demo")
    assert len(res.messages) == 2 and all("1088x1920" in m and "1080x1920" in m for m in res.messages)
    ds = Dataset.open(tmp_path / "demo")  # sizes match: the default check passes
    assert ds.n_frames == 100 and ds.fps == pytest.approx(60)
    assert [c.size for c in ds.rig] == [(1080, 1920), (1080, 1920), (1088, 1920), (1088, 1920)]
    assert ds.frame("cam_02", 0).shape == (1920, 1080, 3)
    for name in ds.camera_names:
        assert len(list(ds.keypoint_dir(name).glob("*.json"))) == 100
    assert res.report["pose_model"] == "body_25b" and res.report["keypoints"].endswith("pose-associated")


def test_frame_offsets_line_the_cameras_up(tmp_path):
    # frame t of camera c is grey 40 c + 25 t, its keypoints at y = h / 2 + t
    trial = make_trial(tmp_path, n_frames=5)
    # keys may name the camera, its video or its keypoint folder
    res = import_pose2sim_trial(trial, tmp_path / "ds", frame_offsets={"cam01": 2, "cam_02": 1, "cam03_json": 0})
    assert res.shifts == {"cam_01": 0, "cam_02": 1, "cam_03": 2} and res.n_frames == 3
    assert res.report["frame_offsets"] == {"cam_01": 2, "cam_02": 1, "cam_03": 0}
    assert any("cam_03 started 0 frames late, its first 2 frames dropped" in m for m in res.messages)
    ds = Dataset.open(tmp_path / "ds")
    assert ds.n_frames == 3
    for c, (name, shift) in enumerate(res.shifts.items()):
        assert ds.frame(name, 0)[0, 0, 0] == pytest.approx(40 * c + 25 * shift, abs=GREY_TOL)
        files = sorted(ds.keypoint_dir(name).iterdir())
        assert len(files) == 3
        first = files[0] if shift == 0 else ds.keypoint_dir(name) / f"{name}_000000000000_keypoints.json"
        y = json.loads(first.read_text())["people"][0]["pose_keypoints_2d"][1]
        assert y == pytest.approx(VIDEO_SIZE[1] / 2 + shift)
    assert res.report["cameras"][2]["frames_dropped_at_start"] == 2
    assert res.report["cameras"][2]["video_action"] == "re-encoded (mp4v) to its frames 2..4"


def test_bad_frame_offsets_and_a_trial_of_videos_only_are_errors(tmp_path):
    trial = make_trial(tmp_path, n_frames=3)
    with pytest.raises(InputError, match=r"frame_offsets.*cam09"):
        import_pose2sim_trial(trial, tmp_path / "ds", frame_offsets={"cam09": 1})
    with pytest.raises(InputError, match="no common frame"):
        import_pose2sim_trial(trial, tmp_path / "ds", frame_offsets={"cam_01": 5})
    shutil.rmtree(trial / "pose")
    (trial / "calibration").mkdir()   # Pose2Sim's current layout: videos and a calibration folder, no keypoints
    with pytest.raises(InputError, match="videos only"):
        import_pose2sim_trial(trial, tmp_path / "ds2")
