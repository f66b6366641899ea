"""recipes/joint_centres.py on a tiny synthetic capture and on C3D files (labelled, static, unlabelled, bad)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from recipes import joint_centres as recipe
from tests.markers.rom_trial import rom_trial
from toolkit.io.c3d import read_c3d, write_c3d
from toolkit.skeleton import JOINTS_14

TINY = """
seed = 5
frames = 40
fps = 100
name = "tiny_markers"

[subject]
height_m = 1.75
motion = "rom"

[markers]
set = "cluster"
noise_px = 0.3
occlusion = 0.05
ghosts = 0.5
cameras = 6
"""


@pytest.fixture(scope="module")
def capture(tmp_path_factory):
    from toolkit.synthetic.marker_capture import generate_marker_capture
    from toolkit.synthetic.spec import parse_spec

    out = tmp_path_factory.mktemp("cap") / "tiny"
    generate_marker_capture(parse_spec(TINY, "tiny.toml"), out)
    return out


def test_recipe_on_a_synthetic_capture(capture, tmp_path, capsys):
    out = tmp_path / "run"
    assert recipe.main([str(capture), "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "labelled correctly" in text
    z = np.load(out / "joint_centres.npz")
    assert z["joints"].shape == (40, 14, 3) and tuple(z["names"]) == JOINTS_14
    assert np.isfinite(z["joints"]).all(axis=-1).mean() > 0.6  # NaN: a joint without its markers in a frame
    sk = json.loads((out / "skeleton.json").read_text())
    assert sk["marker_set"] == "cluster" and 1.5 < sk["height_m"] < 2.0
    assert set(sk["bone_lengths_m"]) == set(f"{a}-{b}" for a, b in
                                            [(JOINTS_14[p], JOINTS_14[c]) for p, c in
                                             [(1, 0), (1, 2), (2, 3), (3, 4), (1, 5), (5, 6), (6, 7),
                                              (1, 8), (8, 9), (9, 10), (1, 11), (11, 12), (12, 13)]])
    m = json.loads((out / "metrics.json").read_text())
    assert 0 < m["labelling"]["share_correct"] <= 1 and m["frames"] == 40
    assert m["joint_error_mm"]["neck"] < 50
    pts = read_c3d(out / "joint_centres.c3d", require_labels=True)
    assert "L_HIP_JC" in pts.labels and "RTH1" in pts.labels
    np.testing.assert_allclose(pts.positions[:, pts.labels.index("L_HIP_JC")], z["joints"][:, 8], atol=1e-5)
    assert (out / "recording.rrd").is_file()
    # the same run again is accepted; other options in the same folder are refused
    assert recipe.main([str(capture), "--out", str(out), "--no-recording"]) == 0
    assert recipe.main([str(capture), "--out", str(out), "--min-rom", "5"]) == 2


def test_recipe_on_labelled_and_static_c3d(tmp_path, capsys):
    traj, truth = rom_trial("cluster", n_frames=150, noise_m=0.0005, seed=2)
    path = write_c3d(tmp_path / "rom.c3d", traj.labels, traj.positions, traj.fps)
    assert recipe.main([str(path), "--out", str(tmp_path / "rom"), "--no-recording"]) == 0
    z = np.load(tmp_path / "rom" / "joint_centres.npz")
    assert list(z["method"][[8, 9, 2, 3]]) == ["score", "sara", "score", "sara"]
    assert np.nanmean(np.linalg.norm(z["joints"][:, 8] - truth[:, 8], axis=-1)) < 0.01
    traj, truth = rom_trial("plug-in-gait", n_frames=60, still=True, noise_m=0.0003)
    path = write_c3d(tmp_path / "static.c3d", traj.labels, traj.positions, traj.fps, units="m")
    assert recipe.main([str(path), "--out", str(tmp_path / "static"), "--no-recording"]) == 0
    assert "functional centres need movement" in capsys.readouterr().out
    sk = json.loads((tmp_path / "static" / "skeleton.json").read_text())
    assert all(v["method"] in ("template", "anatomical") for k, v in sk["joints"].items())
    assert any("functional centres need movement" in m for m in sk["messages"])


def test_recipe_without_labels(tmp_path):
    traj, _ = rom_trial("cluster", n_frames=150, noise_m=0.0003, seed=4)
    keep = [i for i, s in enumerate(traj.segments) if s in ("r_upperarm", "r_forearm", "thorax")]
    path = write_c3d(tmp_path / "anon.c3d", [f"M{i:03d}" for i in range(len(keep))], traj.positions[:, keep], 100.0)
    assert recipe.main([str(path), "--out", str(tmp_path / "anon"), "--no-recording"]) == 0
    z = np.load(tmp_path / "anon" / "joint_centres.npz")
    assert np.isnan(z["joints"]).all() and len(z["pair_names"]) == 2
    sk = json.loads((tmp_path / "anon" / "skeleton.json").read_text())
    assert not sk["labelled"] and len(sk["subsets"]) == 3


def test_recipe_bad_inputs(tmp_path, capsys):
    import ezc3d

    c = ezc3d.c3d()
    c["parameters"]["POINT"]["RATE"]["value"] = [100.0]
    c["parameters"]["POINT"]["LABELS"]["value"] = ["A", "B", "C"]
    c.add_parameter("POINT", "UNITS", ["in"])
    c["data"]["points"] = np.ones((4, 3, 5))
    c.write(str(tmp_path / "inches.c3d"))
    assert recipe.main([str(tmp_path / "inches.c3d"), "--out", str(tmp_path / "o1")]) == 2
    assert "POINT:UNITS" in capsys.readouterr().err
    assert recipe.main([str(tmp_path / "absent.c3d"), "--out", str(tmp_path / "o2")]) == 2
    (tmp_path / "empty").mkdir()
    assert recipe.main([str(tmp_path / "empty"), "--out", str(tmp_path / "o3")]) == 2
    assert "calibration" in capsys.readouterr().err


def test_recording_reports_are_declared():
    from toolkit.markers.functional import joint_centres
    from toolkit.observe import RecordingObserver
    from toolkit.pipeline.joint_centres import report_centres

    traj, _ = rom_trial("plug-in-gait", n_frames=50)
    obs = RecordingObserver()  # strict: an undeclared kind or field fails
    report_centres(obs, traj, joint_centres(traj, observer=obs), max_frames=20)
    assert {"joints3d", "lines3d", "points3d", "skeleton", "text"} <= obs.kinds
    assert len(obs.of_kind("joints3d")) == 20
    assert any(d.get("name") == "markers/spheres" for d in obs.of_kind("lines3d"))
    assert any(d.get("name") == "markers/axes" for d in obs.of_kind("lines3d"))
