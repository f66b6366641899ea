"""Pose2Sim session folders (toolkit.io.pose2sim)."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from toolkit.errors import InputError
from toolkit.io.pose2sim import is_pose2sim_trial, read_pose2sim_trial

REPO_ROOT = Path(__file__).resolve().parents[2]


def _session(root: Path, participant=True, session_cfg="[project]\nframe_rate = 60\n[pose]\npose_model = 'BODY_25B'\n"):
    (root / "S00_Calibration").mkdir(parents=True)
    (root / "S00_Calibration" / "Calib_board.toml").write_text("")
    (root / "Config.toml").write_text(session_cfg)
    trial = root / ("P00" if participant else "") / "T01"
    (trial / "pose" / "cam01_json").mkdir(parents=True)
    return trial


def test_trial_with_participant_level_and_config_precedence(tmp_path):
    trial = _session(tmp_path)
    (tmp_path / "P00" / "Config.toml").write_text("[project]\nframe_rate = 50\n")
    (trial / "Config.toml").write_text("[pose]\npose_model = 'HALPE_26'\n")
    assert is_pose2sim_trial(trial) and not is_pose2sim_trial(tmp_path)
    t = read_pose2sim_trial(trial)
    assert t.keypoints == trial / "pose" and t.calibration == tmp_path / "S00_Calibration" / "Calib_board.toml"
    assert t.pose_model == "halpe_26" and t.frame_rate == 50.0        # trial over participant over session
    assert [f.parent for f in t.config_files] == [tmp_path, tmp_path / "P00", trial]
    (trial / "pose-associated" / "cam01_json").mkdir(parents=True)
    assert read_pose2sim_trial(trial).keypoints == trial / "pose-associated"
    # the raw detections asked for explicitly: the trial's settings still apply
    assert is_pose2sim_trial(trial / "pose")
    t = read_pose2sim_trial(trial / "pose")
    assert t.trial == trial and t.keypoints == trial / "pose" and t.pose_model == "halpe_26"
    # a folder merely called "pose" with nothing of Pose2Sim around is not a trial
    other = tmp_path / "a" / "b" / "elsewhere" / "pose"
    (other / "cam1").mkdir(parents=True)
    assert not is_pose2sim_trial(other)


def test_trial_without_participant_level_and_auto_rate(tmp_path):
    trial = _session(tmp_path, participant=False, session_cfg="[project]\nframe_rate = 'auto'\n")
    t = read_pose2sim_trial(trial)
    assert t.frame_rate is None and t.pose_model is None and t.calibration is not None


@pytest.mark.parametrize("cfg,match", [("[pose]\npose_model = 'BODY_135'\n", "pose_model"),
                                       ("[project]\nframe_rate = -3\n", "frame_rate"),
                                       ("[project\n", "Config.toml")])
def test_bad_settings_name_the_file(tmp_path, cfg, match):
    trial = _session(tmp_path, session_cfg=cfg)
    with pytest.raises(InputError, match=match) as e:
        read_pose2sim_trial(trial)
    assert "Config.toml" in str(e.value)


def test_not_a_trial(tmp_path):
    with pytest.raises(InputError, match="pose-associated"):
        read_pose2sim_trial(tmp_path)


@pytest.mark.realdata
def test_demo_session():
    root = Path(os.environ.get("TOOLKIT_REALDATA", REPO_ROOT.parent / "shared" / "realdata")) / "pose2sim_demo"
    trial = root / "S00_P00_SingleParticipant" / "S00_P00_T00_StaticTrial"
    if not trial.is_dir():
        pytest.skip(f"real data not found at {root}")
    t = read_pose2sim_trial(trial)
    assert t.keypoints.name == "pose-associated" and t.calibration.name == "Calib_qualisys.toml"
    assert t.pose_model == "body_25b" and t.frame_rate == 60.0 and len(t.reference_trc) == 3


def test_keypoint_session_from_a_trial(tmp_path):
    """open_keypoint_session: the session's calibration, the Config's format and rate, cameras by name."""
    import json

    import numpy as np

    from toolkit.cameras import Camera, Rig
    from toolkit.io import write_calibration
    from toolkit.pipeline.keypoint_session import open_keypoint_session

    trial = _session(tmp_path, session_cfg="[project]\nframe_rate = 50\n[pose]\npose_model = 'COCO_17'\n")
    (tmp_path / "S00_Calibration" / "Calib_board.toml").unlink()
    rig = Rig(tuple(Camera.look_at(f"cam_{i:02d}", [4 * np.cos(a), 4 * np.sin(a), 1.5], [0, 0, 1],
                                   size=(640, 480), focal_px=600.0) for i, a in ((1, 0.0), (2, 1.5))))
    write_calibration(tmp_path / "S00_Calibration" / "Calib_scene.toml", rig)
    kp = np.tile([100.0, 200.0, 0.9], 17).tolist()
    for cam in ("cam02_json", "cam01_json"):
        (trial / "pose" / cam).mkdir(parents=True, exist_ok=True)
        for t in range(2):
            (trial / "pose" / cam / f"x.{t:04d}.json").write_text(json.dumps({"people": [{"pose_keypoints_2d": kp}]}))
    s = open_keypoint_session(trial)
    assert s.rig.names == ["cam_01", "cam_02"] and [p.name for p in s.sources] == ["cam01_json", "cam02_json"]
    assert s.matching == "by name" and s.calibration.name == "Calib_scene.toml"
    assert s.keypoints.format.fmt == "coco_17" and "pose_model" in s.keypoints.format.reason
    assert (s.fps, s.fps_from) == (50.0, "Pose2Sim Config.toml") and s.keypoints.keypoints.shape == (2, 2, 17, 3)
    assert open_keypoint_session(trial, fps=25.0).fps_from == "--fps"
    with pytest.raises(InputError, match="calibration"):
        open_keypoint_session(trial / "pose" / "cam01_json" / "..")  # a plain folder: no calibration known
