"""Reader of OpenPose JSON folders (toolkit.io.openpose)."""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import pytest

from toolkit.errors import InputError
from toolkit.io.openpose import camera_folders, read_openpose_cameras, read_openpose_folder, read_openpose_json

REPO_ROOT = Path(__file__).resolve().parents[2]


def _person(n=25, value=1.0, conf=0.8):
    kp = np.tile([value, 2 * value, conf], n)
    kp[3:6] = 0.0                    # keypoint 1 undetected
    return kp.tolist()


def _write(path: Path, people):
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps({"version": 1.3, "people": people}))


def test_read_json_people(tmp_path):
    f = tmp_path / "a.json"
    _write(f, [{"pose_keypoints_2d": _person(value=1.0, conf=0.2)}, {"pose_keypoints_2d": _person(value=5.0)}])
    kp = read_openpose_json(f, 25)
    assert kp.shape == (25, 3)
    assert kp[0].tolist() == [5.0, 10.0, 0.8]                      # the most confident person
    assert np.isnan(kp[1, :2]).all() and kp[1, 2] == 0.0           # (0, 0, 0) -> missing
    assert read_openpose_json(f, 25, person="first")[0, 0] == 1.0
    _write(f, [{}])                                                # Pose2Sim: nobody associated
    empty = read_openpose_json(f, 25)
    assert empty.shape == (25, 3) and np.isnan(empty[:, :2]).all() and (empty[:, 2] == 0).all()
    _write(f, [])
    assert np.isnan(read_openpose_json(f, 25)[:, :2]).all()


@pytest.mark.parametrize("content,match", [
    ("{not json", "JSON syntax error"),
    (json.dumps({"people": [{"pose_keypoints_2d": [1, 2, 3, 4]}]}), "triples"),
    (json.dumps({"people": [{"pose_keypoints_2d": [1, 2, 0.5] * 17}]}), "25 keypoints"),
    (json.dumps({"people": "nobody"}), "people"),
])
def test_bad_json_names_the_file(tmp_path, content, match):
    f = tmp_path / "cam01.0003.json"
    f.write_text(content)
    with pytest.raises(InputError, match=match) as e:
        read_openpose_json(f, 25)
    assert "cam01.0003.json" in str(e.value)
    with pytest.raises(InputError, match="no such file"):
        read_openpose_json(tmp_path / "missing.json", 25)


def test_folders_aligned_on_frame_numbers(tmp_path):
    for i in (0, 1, 2, 10):
        _write(tmp_path / "cam01_json" / f"cam01.{i:04d}.json", [{"pose_keypoints_2d": _person(value=i + 1)}])
    for i in (0, 2):                                               # a shorter camera
        _write(tmp_path / "cam02_json" / f"x_{i:012d}_keypoints.json", [{"pose_keypoints_2d": _person(value=i + 1)}])
    (tmp_path / "notes.txt").write_text("not a camera")
    one = read_openpose_folder(tmp_path / "cam01_json", 25)
    assert one.frames.tolist() == [0, 1, 2, 10] and one.files[-1] == "cam01.0010.json"
    folders, frames, kp = read_openpose_cameras(tmp_path, 25)
    assert [f.folder.name for f in folders] == ["cam01_json", "cam02_json"]
    assert frames.tolist() == [0, 1, 2, 10] and kp.shape == (2, 4, 25, 3)
    assert kp[1, 2, 0, 0] == 3.0 and np.isnan(kp[1, 1, :, :2]).all() and (kp[1, 1, :, 2] == 0).all()
    _, frames, kp = read_openpose_cameras(tmp_path, 25, max_frames=2)
    assert frames.tolist() == [0, 1] and kp.shape == (2, 2, 25, 3)


def test_folder_errors(tmp_path):
    with pytest.raises(InputError, match="no such folder"):
        camera_folders(tmp_path / "nope")
    with pytest.raises(InputError, match="no sub-folders"):
        camera_folders(tmp_path)
    (tmp_path / "cam01").mkdir()
    with pytest.raises(InputError, match=r"\*\.json"):
        read_openpose_folder(tmp_path / "cam01", 25)


def test_pose2sim_demo_folder():
    root = Path(os.environ.get("TOOLKIT_REALDATA", REPO_ROOT.parent / "shared" / "realdata"))
    assoc = root / "pose2sim_demo" / "S00_P00_SingleParticipant" / "S00_P00_T01_BalancingTrial" / "pose-associated"
    if not assoc.is_dir():
        pytest.skip(f"real data not found at {assoc}")
    folders, frames, kp = read_openpose_cameras(assoc, 25)
    assert len(folders) == 4 and frames.tolist() == list(range(100)) and kp.shape == (4, 100, 25, 3)
    # cam03.0052.json holds a person without pose_keypoints_2d: missing, not an error
    assert np.isnan(kp[2, 52, :, :2]).all() and np.isfinite(kp[2, 51, 5, :2]).all()
