"""End-to-end tests of recipes/import_pose2sim.py."""

from __future__ import annotations

import importlib
import json

import pytest

from tests.io.pose2sim_trial import make_trial
from toolkit.io import Dataset



def load_recipe():
    return importlib.import_module("recipes.import_pose2sim")


def test_recipe_imports_a_trial_and_reports_mismatches(tmp_path, capsys):
    trial = make_trial(tmp_path, n_frames=[4, 3, 4], calib_size=(72, 48), pose_folders=("pose", "pose-associated"))
    rc = load_recipe().main([str(trial), "--out", str(tmp_path / "ds"), "--pose", "pose"])
    out = capsys.readouterr().out
    assert rc == 0
    assert out.count("kept K") == 3 and "trimmed to the common length 3" in out and "wrote" in out
    ds = Dataset.open(tmp_path / "ds")
    assert ds.n_frames == 3 and ds.rig["cam_02"].size == (64, 48)
    rep = json.loads((tmp_path / "ds" / "import.json").read_text())
    assert rep["keypoints"].endswith("pose") and rep["n_frames"] == 3


@pytest.mark.parametrize("breakage, words", [("calibration", "calibration"), ("video", "fewer videos")])
def test_recipe_bad_input_exits_with_a_clear_message(tmp_path, capsys, breakage, words):
    trial = make_trial(tmp_path, with_calibration=breakage != "calibration")
    if breakage == "video":
        (trial / "videos" / "cam02.mp4").unlink()
    rc = load_recipe().main([str(trial), "--out", str(tmp_path / "ds")])
    err = capsys.readouterr().err
    assert rc == 2 and err.startswith("error: ") and words in err
    assert not (tmp_path / "ds" / "import.json").exists()
