"""recipes/joint_angles.py end to end on synthetic runs of each output kind; the reports to the observer."""

from __future__ import annotations

import numpy as np
import pytest

from recipes import joint_angles as recipe
from toolkit.biomech.files import load_run, read_angles_csv
from toolkit.biomech.mapping import joints_to_points
from toolkit.biomech.run import JointAnglesConfig, run
from toolkit.biomech.synthetic import posed_points, random_rotation, smooth_motion
from toolkit.errors import InputError
from toolkit.observe import RecordingObserver
from toolkit.skeleton import JOINTS_13, JOINTS_14

#: angles.csv keeps 4 decimals.
CSV_DEG = 1e-3


def _run_folder(tmp_path, rng, n_frames=25, kind="poses3d"):
    # flexion only: the plane of each bent limb then gives its axes exactly (segments.py)
    truth = {k: v for k, v in smooth_motion(n_frames, rng).items() if k.endswith("flexion")}
    pts = posed_points(truth, n_frames, body=random_rotation(rng))
    folder = tmp_path / kind
    folder.mkdir()
    if kind == "poses3d":
        joints = np.stack([pts[n] for n in JOINTS_14], 1)
        np.savez(folder / "poses3d.npz", joints=joints, names=np.array(JOINTS_14), frame_rate=np.array(50.0))
    else:       # the depth system's 13 joints: hands at the wrists, feet at the ankles
        src = {"l_hand": "l_wrist", "r_hand": "r_wrist", "l_foot": "l_ankle", "r_foot": "r_ankle"}
        joints = np.stack([pts[src.get(n, n)] for n in JOINTS_13], 1)
        np.savez(folder / "skeleton.npz", joints=joints, names=np.array(JOINTS_13))
    return truth, pts, folder


def test_recipe_writes_angles_bvh_gltf_and_summary(tmp_path):
    truth, _, folder = _run_folder(tmp_path, np.random.default_rng(21))
    out = tmp_path / "out"
    assert recipe.main([str(folder), "--out", str(out), "--bvh", "--gltf", "--no-recording"]) == 0
    a = read_angles_csv(out / "angles.csv")
    assert a.names[0] == "l_hip_flexion" and "r_elbow_flexion" in a.names
    assert "l_ankle_dorsiflexion" not in a.names          # no toe in a 14-joint run
    np.testing.assert_allclose(a.time, np.arange(25) / 50.0, atol=1e-6)
    for name in ("l_knee_flexion", "r_hip_flexion", "l_elbow_flexion", "r_shoulder_flexion"):
        np.testing.assert_allclose(a[name], truth[name], atol=CSV_DEG, err_msg=name)
    for f in ("motion.bvh", "motion.glb", "summary.json"):
        assert (out / f).stat().st_size > 0


def test_depth_skeleton_maps_hands_and_feet(tmp_path):
    truth, _, folder = _run_folder(tmp_path, np.random.default_rng(22), kind="depth")
    with pytest.raises(InputError, match="frame rate"):
        run(JointAnglesConfig(recording=False), source=folder, out=tmp_path / "o1")
    res = run(JointAnglesConfig(fps=30.0, recording=False), source=folder, out=tmp_path / "o2")
    np.testing.assert_allclose(res.angles["r_knee_flexion"], truth["r_knee_flexion"], atol=1e-6)
    np.testing.assert_allclose(res.angles["l_elbow_flexion"], truth["l_elbow_flexion"], atol=1e-6)
    assert res.system == "depth"


def test_angles_reported_as_scalars_per_joint(tmp_path):
    _, _, folder = _run_folder(tmp_path, np.random.default_rng(23), n_frames=5)
    obs = RecordingObserver()
    res = run(JointAnglesConfig(recording=False), source=folder, out=tmp_path / "o", observer=obs)
    scalars = obs.of_kind("scalar")
    assert len(scalars) == 5 * len(res.angles.names)
    names = {s["name"] for s in scalars}
    assert "angles/l_knee/flexion" in names and "angles/r_hip/adduction" in names and len(names) == 16
    knee = [s["value"] for s in scalars if s["name"] == "angles/l_knee/flexion"]
    np.testing.assert_allclose(knee, res.angles["l_knee_flexion"])
    assert [s["frame"] for s in scalars if s["name"] == "angles/l_knee/flexion"] == list(range(5))
    assert len(obs.of_kind("joints3d")) == 5


def test_marker_run_takes_the_labelled_markers(tmp_path):
    rng = np.random.default_rng(24)
    pts = posed_points({"l_knee_flexion": 30.0}, 4, body=random_rotation(rng))
    folder = tmp_path / "markers"
    folder.mkdir()
    np.savez(folder / "joint_centres.npz", joints=np.stack([pts[n] for n in JOINTS_14], 1),
             names=np.array(JOINTS_14), fps=np.array(100.0))
    np.savez(folder / "trajectories.npz", labels=np.array(["LTOE", "RHEE", "XYZ"]),
             positions=np.zeros((4, 3, 3)))
    data = load_run(folder)
    assert data.fps == 100.0 and data.system == "markers"
    assert "l_toe" in data.points and "r_heel" in data.points and "XYZ" not in data.points


def test_bad_inputs_name_what_is_wrong(tmp_path):
    with pytest.raises(InputError, match="run folder"):
        load_run(tmp_path)
    with pytest.raises(InputError, match="names"):
        joints_to_points(np.zeros((3, 14, 3)), ["a"] * 14)
    with pytest.raises(InputError, match="engine"):
        run(JointAnglesConfig(engine="x"), source=tmp_path, out=tmp_path / "o")
    assert recipe.main([str(tmp_path / "missing"), "--out", str(tmp_path / "o")]) == 2
