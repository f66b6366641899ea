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


@pytest.mark.parametrize("cfg,match", [("[pose]\npose_model = 'BLAZEPOSE'\n", "pose_model"),
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
