"""End-to-end tests of recipes/pose_from_keypoints.py."""

from __future__ import annotations

import importlib
import json
import os
from pathlib import Path

import numpy as np
import pytest

from toolkit.anthropometry import BodyProportions
from toolkit.cameras import Camera, Rig
from toolkit.io import write_calibration
from toolkit.motion import generate_motion
from toolkit.skeleton import JOINTS_14
from toolkit.skeleton.mappings import BODY_25B

REPO_ROOT = Path(__file__).resolve().parents[2]
#: Keypoint noise of the synthetic detections, pixels.
NOISE_PX = 0.5
#: MPJPE of the synthetic scene: 0.5 px at 4 m with f = 600 px is 3 mm per view; the gauge
#: of the offsets adds at most a few millimetres (measured 2-4 mm).
SYNTHETIC_MPJPE_M = 0.015
#: BODY_25B keypoints that carry our 14 joints (head = mean of the ears, neck = UpperNeck).
SOURCE_OF = {"LEar": "head", "REar": "head", "UpperNeck": "neck",
             **{f"{s}{n.capitalize()}": f"{s.lower()}_{n}" for s in ("L", "R")
                for n in ("shoulder", "elbow", "wrist", "hip", "knee", "ankle")}}


def load_recipe():
    return importlib.import_module("recipes.pose_from_keypoints")


def make_scene(root: Path, n_frames=3, seed=0):
    """Calibration and OpenPose folders for a walking person seen by three cameras."""
    rng = np.random.default_rng(seed)
    poses = generate_motion("walk", BodyProportions.from_height(1.75), n_frames, 25, rng)
    centre = poses[:, :, :2].mean(axis=(0, 1))
    poses = poses - np.array([centre[0], centre[1], 0.0])
    cams = [Camera.look_at(f"cam_{i + 1:02d}", [4 * np.cos(a), 4 * np.sin(a), 1.5], [0, 0, 1], size=(640, 480),
                           focal_px=600.0) for i, a in enumerate(np.radians([0, 80, 160]))]
    rig = Rig(tuple(cams))
    write_calibration(root / "calib.toml", rig)
    kp_root = root / "keypoints"
    for c, cam in enumerate(rig):
        folder = kp_root / f"cam{c + 1:02d}_json"
        folder.mkdir(parents=True)
        for t in range(n_frames):
            uv = cam.project(poses[t]) + rng.normal(0, NOISE_PX, (14, 2))
            kp = np.zeros((25, 3))
            for name, joint in SOURCE_OF.items():
                kp[BODY_25B.index(name)] = [*uv[JOINTS_14.index(joint)], 0.9]
            people = [{"person_id": [-1], "pose_keypoints_2d": kp.ravel().tolist()}]
            if t == n_frames - 1 or (t == 1 and c == 2):
                people = [{}]      # nobody (last frame: nobody anywhere; frame 1: camera 3 only)
            (folder / f"cam{c + 1:02d}.{t:04d}.json").write_text(json.dumps({"version": 1.3, "people": people}))
    return rig, poses, kp_root


def run(argv):
    return load_recipe().main([str(a) for a in argv])


def test_help(capsys):
    with pytest.raises(SystemExit) as e:
        run(["--help"])
    assert e.value.code == 0
    assert "--keypoints" in capsys.readouterr().out


def test_synthetic_end_to_end(tmp_path, capsys):
    rig, poses, kp_root = make_scene(tmp_path, n_frames=4)
    out = tmp_path / "out"
    assert run(["--calibration", tmp_path / "calib.toml", "--keypoints", kp_root, "--out", out, "--quiet"]) == 0
    printed = capsys.readouterr().out
    assert str(out / "poses3d.npz") in printed and "cam_01 <- cam01_json" in printed
    p3 = np.load(out / "poses3d.npz")
    assert p3["joints"].shape == (4, 14, 3) and list(p3["names"]) == list(JOINTS_14)
    assert list(p3["success"]) == [True, True, True, False]
    err = np.linalg.norm(p3["joints"][:3] - poses[:3], axis=-1)
    assert err.mean() < SYNTHETIC_MPJPE_M
    assert np.isnan(p3["joints"][3]).all()                      # the empty frame: NaN, no crash
    off = np.load(out / "offsets.npz")
    assert off["offsets"].shape == (4, 3, 2) and list(off["camera_names"]) == rig.names
    assert np.isnan(off["offsets"][1, 2]).all()                 # camera 3 missing in frame 1
    p2 = np.load(out / "poses2d.npz")
    assert p2["cam_01"].shape == (4, 14, 2) and "cam_01_raw" in p2.files
    assert (out / "recording.rrd").stat().st_size > 0
    assert (out / "anthropometry.txt").read_text().count("frame") == 4


def test_camera_count_mismatch(tmp_path, capsys):
    _, _, kp_root = make_scene(tmp_path, n_frames=2)
    (kp_root / "cam03_json").rename(tmp_path / "elsewhere")
    code = run(["--calibration", tmp_path / "calib.toml", "--keypoints", kp_root, "--out", tmp_path / "o",
                "--no-recording", "--quiet"])
    err = capsys.readouterr().err
    assert code == 2
    assert "cam_01" in err and "cam_03" in err and "cam01_json" in err and "2:" in err


def test_unreadable_json_is_named(tmp_path, capsys):
    _, _, kp_root = make_scene(tmp_path, n_frames=2)
    bad = kp_root / "cam02_json" / "cam02.0001.json"
    bad.write_text("{broken")
    code = run(["--calibration", tmp_path / "calib.toml", "--keypoints", kp_root, "--out", tmp_path / "o",
                "--no-recording", "--quiet"])
    assert code == 2 and "cam02.0001.json" in capsys.readouterr().err


def test_missing_inputs(tmp_path, capsys):
    make_scene(tmp_path, n_frames=1)
    assert run(["--calibration", tmp_path / "nope.toml", "--keypoints", tmp_path / "keypoints",
                "--out", tmp_path / "o", "--quiet"]) == 2
    assert "nope.toml" in capsys.readouterr().err
    assert run(["--calibration", tmp_path / "calib.toml", "--keypoints", tmp_path / "nothing",
                "--out", tmp_path / "o", "--quiet"]) == 2
    assert "nothing" in capsys.readouterr().err


def test_interrupted_run_keeps_earlier_frames(tmp_path, monkeypatch):
    _, poses, kp_root = make_scene(tmp_path, n_frames=4)
    import toolkit.multiview.keypoint_sequence as ks

    calls = {"n": 0}
    real_select = ks.select_multiview

    def select(*a, **k):  # Ctrl-C while the third frame is triangulated
        calls["n"] += 1
        if calls["n"] == 3:
            raise KeyboardInterrupt
        return real_select(*a, **k)

    monkeypatch.setattr(ks, "select_multiview", select)
    out = tmp_path / "out"
    code = run(["--calibration", tmp_path / "calib.toml", "--keypoints", kp_root, "--out", out,
                "--no-recording", "--quiet"])
    assert code == 130
    p3 = np.load(out / "poses3d.npz")
    assert list(p3["success"]) == [True, True, False, False]
    assert np.linalg.norm(p3["joints"][:2] - poses[:2], axis=-1).mean() < SYNTHETIC_MPJPE_M


def _demo_paths():
    root = Path(os.environ.get("TOOLKIT_REALDATA", REPO_ROOT.parent / "shared" / "realdata")) / "pose2sim_demo"
    trial = root / "S00_P00_SingleParticipant" / "S00_P00_T01_BalancingTrial"
    if not trial.is_dir():
        pytest.skip(f"real data not found at {root}")
    return root / "S00_Calibration" / "Calib_qualisys.toml", trial


#: Pose2Sim demo: median distance (mm) between our joints and Pose2Sim's own triangulation
#: over the joints that correspond (measured 20-35 mm per joint on the first frames;
#: see docs/stage1_multiview.md).
DEMO_VS_POSE2SIM_M = 0.06
#: Median reprojection error of our joints against the offset-corrected OpenPose keypoints on
#: the demo, pixels (measured 7.5 px over the 100 frames).
DEMO_REPROJECTION_PX = 10.0
#: Against the raw keypoints (measured 17.8 px: the offsets, up to the 16 px bound here, move
#: the body; Pose2Sim's own .trc gives 10.7 px).
DEMO_RAW_REPROJECTION_PX = 25.0


@pytest.mark.realdata
def test_pose2sim_demo_first_frames(tmp_path):
    from toolkit.io import read_calibration
    from toolkit.io.openpose import read_openpose_cameras
    from toolkit.skeleton.mappings import to_skeleton14

    calib, trial = _demo_paths()
    out = tmp_path / "demo"
    assert run(["--calibration", calib, "--keypoints", trial / "pose-associated", "--out", out,
                "--max-frames", 5, "--no-recording", "--quiet"]) == 0
    joints = np.load(out / "poses3d.npz")["joints"]
    assert joints.shape == (5, 14, 3) and np.isfinite(joints[:, 1:]).all()
    # against Pose2Sim's own triangulation (.trc, Y-up: world = (Z, X, Y))
    trc = np.loadtxt(next((trial / "pose-3d").glob("*_0-100.trc")), skiprows=5)[:5, 2:].reshape(5, -1, 3)
    names = ["RHip", "RKnee", "RAnkle", "RBigToe", "RSmallToe", "RHeel", "LHip", "LKnee", "LAnkle", "LBigToe",
             "LSmallToe", "LHeel", "Neck", "Head", "Nose", "RShoulder", "RElbow", "RWrist", "LShoulder",
             "LElbow", "LWrist"]
    theirs = trc[..., [2, 0, 1]]
    pairs = [(f"{s.lower()}_{n}", f"{s}{n.capitalize()}") for s in "LR"
             for n in ("shoulder", "elbow", "wrist", "hip", "knee", "ankle")]
    d = [np.linalg.norm(joints[:, JOINTS_14.index(a)] - theirs[:, names.index(b)], axis=-1) for a, b in pairs]
    assert np.median(d) < DEMO_VS_POSE2SIM_M
    # reprojection against the raw detections
    rig = read_calibration(calib)
    rig = Rig(tuple(sorted(rig, key=lambda c: c.name)))
    _, _, kp = read_openpose_cameras(trial / "pose-associated", 25, max_frames=5)
    kp14 = to_skeleton14(kp, "body_25b", confidence=True, min_confidence=0.3)
    proj = rig.project(joints)                                    # (C, T, 14, 2)
    raw = np.linalg.norm(proj - kp14[..., :2], axis=-1)
    offsets = np.load(out / "offsets.npz")["offsets"]             # (T, C, 2)
    corrected = np.linalg.norm(proj - kp14[..., :2] - np.transpose(offsets, (1, 0, 2))[:, :, None], axis=-1)
    assert np.nanmedian(corrected) < DEMO_REPROJECTION_PX
    assert np.nanmedian(raw) < DEMO_RAW_REPROJECTION_PX
    assert np.nanmedian(corrected) < np.nanmedian(raw)


#: Static trial with defaults: median distance to Pose2Sim's .trc over the 12 limb joints (issue 14:
#: <= 5 mm; measured 2 mm).
STATIC_VS_POSE2SIM_M = 0.005


@pytest.mark.realdata
def test_pose2sim_static_trial_is_not_mirrored(tmp_path):
    """A correctly labelled person standing still: defaults keep the labels (no view flipped, no mirror)."""
    _, trial = _demo_paths()
    static = trial.parent / "S00_P00_T00_StaticTrial"
    out = tmp_path / "static"
    assert run(["--keypoints", static, "--out", out, "--no-recording", "--quiet", "--export", "none"]) == 0
    joints = np.load(out / "poses3d.npz")["joints"]
    assert (np.load(out / "flips.npz")["flips"] == "").all()
    names = [ln for ln in (next((static / "pose-3d").glob("*_0-12.trc"))).read_text().splitlines()[3].split("\t")
             if ln.strip()][2:]
    trc = np.loadtxt(next((static / "pose-3d").glob("*_0-12.trc")), skiprows=5)[:, 2:].reshape(len(joints), -1, 3)
    theirs = trc[..., [2, 0, 1]]
    pairs = [(f"{s.lower()}_{n}", f"{s}{n.capitalize()}") for s in "LR"
             for n in ("shoulder", "elbow", "wrist", "hip", "knee", "ankle")]
    d = np.concatenate([np.linalg.norm(joints[:, JOINTS_14.index(a)] - theirs[:, names.index(b)], axis=-1)
                        for a, b in pairs])
    assert np.nanmedian(d) < STATIC_VS_POSE2SIM_M
    mirrored = np.concatenate([np.linalg.norm(joints[:, JOINTS_14.index(a)] - theirs[:, names.index(
        ("R" if b[0] == "L" else "L") + b[1:])], axis=-1) for a, b in pairs])
    assert np.nanmedian(mirrored) > 10 * np.nanmedian(d)


def test_config_file_flags_win_unknown_keys_rejected(tmp_path, capsys):
    _, poses, kp_root = make_scene(tmp_path, n_frames=3)
    cfg = tmp_path / "run.toml"
    cfg.write_text('export = ["csv"]\nflips = []\noffsets = "frame"\nfilter_cutoff = 6.0\nfps = 25.0\n')
    out = tmp_path / "out"
    assert run(["--calibration", tmp_path / "calib.toml", "--keypoints", kp_root, "--out", out, "--quiet",
                "--no-recording", "--config", cfg, "--offsets", "none"]) == 0
    assert sorted(p.name for p in out.glob("poses3d*.*")) == ["poses3d.csv", "poses3d.json", "poses3d.npz",
                                                              "poses3d_filt_butterworth.csv"]
    assert str(np.load(out / "offsets.npz")["mode"]) == "none"            # the flag won over the file
    meta = json.loads((out / "poses3d.json").read_text())
    ident = meta["run"]["config"]
    assert ident["flips"] == [] and ident["offsets"] == "none" and ident["export"] == ["csv"]
    assert "progress" not in ident and "recording" not in ident           # runtime options: not the identity
    assert np.linalg.norm(np.load(out / "poses3d.npz")["joints"][:2] - poses[:2], axis=-1).mean() < SYNTHETIC_MPJPE_M
    cfg.write_text('offset = "frame"\n')
    assert run(["--calibration", tmp_path / "calib.toml", "--keypoints", kp_root, "--out", tmp_path / "o2",
                "--quiet", "--config", cfg]) == 2
    err = capsys.readouterr().err
    assert str(cfg) in err and "offset" in err and "offsets" in err
    assert run(["--calibration", tmp_path / "calib.toml", "--keypoints", kp_root, "--out", tmp_path / "o3",
                "--quiet", "--export", "trc,pdf"]) == 2
    assert "--export" in capsys.readouterr().err
