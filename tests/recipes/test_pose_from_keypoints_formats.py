"""pose_from_keypoints with the peers' formats in and out: MMPose / COCO input, TRC / C3D / CSV output,
filtering, Pose2Sim trial folders, bad input."""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import pytest

from toolkit.io.trajectories import read_c3d, read_csv, read_trc
from toolkit.skeleton import JOINTS_14
from tests.recipes.test_pose_from_keypoints import SYNTHETIC_MPJPE_M, make_scene, run
from toolkit.skeleton.mappings import BODY_25B, POSE2SIM_MARKERS

REPO_ROOT = Path(__file__).resolve().parents[2]
#: Written trajectories read back equal the triangulated joints to 0.1 mm (the issue's figure).
ROUND_TRIP_M = 1e-4
#: The same detections in another file layout give the same joints.
SAME_LIMBS_M = 1e-6


def _openpose_people(path: Path):
    people = json.loads(path.read_text())["people"]
    return [np.array(p["pose_keypoints_2d"], float).reshape(-1, 3) for p in people if p]


def _to_other_layouts(kp_root: Path, out: Path):
    """The OpenPose folders rewritten as MMPose video predictions (BODY_25B names) and COCO-17 results."""
    mm, coco = out / "mmpose", out / "coco"
    mm.mkdir(parents=True)
    coco.mkdir(parents=True)
    names = {str(i): n for i, n in enumerate(BODY_25B)}
    for cam in sorted(kp_root.iterdir()):
        frames, results = [], []
        for t, f in enumerate(sorted(cam.iterdir())):
            people = _openpose_people(f)
            frames.append({"frame_id": t, "instances": [{"keypoints": p[:, :2].tolist(),
                                                         "keypoint_scores": p[:, 2].tolist()} for p in people]})
            results += [{"image_id": t, "category_id": 1, "keypoints": p[:17].ravel().tolist(), "score": 0.9}
                        for p in people]
        (mm / f"{cam.name}.json").write_text(json.dumps({"meta_info": {"keypoint_id2name": names},
                                                         "instance_info": frames}))
        (coco / f"{cam.name}.json").write_text(json.dumps(results))
    return mm, coco


def test_mmpose_and_coco_inputs_give_the_openpose_result(tmp_path, capsys):
    _, poses, kp_root = make_scene(tmp_path, n_frames=3)
    mm, coco = _to_other_layouts(kp_root, tmp_path)
    joints = {}
    for name, root in (("openpose", kp_root), ("mmpose", mm), ("coco", coco)):
        out = tmp_path / f"out_{name}"
        assert run(["--calibration", tmp_path / "calib.toml", "--keypoints", root, "--out", out, "--quiet",
                    "--no-recording", "--export", "none"]) == 0
        joints[name] = np.load(out / "poses3d.npz")["joints"]
    printed = capsys.readouterr().out
    assert "format body_25b (keypoint names in cam01_json.json)" in printed
    assert "format coco_17 (17 keypoints per person)" in printed and "matched by name" in printed
    assert "cam_03: 0 frames without a file, 2 with nobody" in printed
    # the same BODY_25B detections in MMPose's layout: the same joints
    assert np.max(np.abs(joints["mmpose"][:2] - joints["openpose"][:2])) < SAME_LIMBS_M
    # COCO-17 has no upper neck (the neck is the shoulders' middle): other joints, as close to the truth
    assert np.linalg.norm(joints["coco"][:2] - poses[:2], axis=-1).mean() < SYNTHETIC_MPJPE_M


def test_exports_round_trip_and_filter_metadata(tmp_path, capsys):
    import ezc3d

    _, _, kp_root = make_scene(tmp_path, n_frames=4)
    out = tmp_path / "out"
    assert run(["--calibration", tmp_path / "calib.toml", "--keypoints", kp_root, "--out", out, "--quiet",
                "--no-recording", "--fps", 25, "--filter-cutoff", 6]) == 0
    p3 = np.load(out / "poses3d.npz")
    joints = p3["joints"]
    assert float(p3["frame_rate"]) == 25.0 and "cut-off 6 Hz" in str(p3["filter"])
    assert p3["joints_filtered"].shape == joints.shape
    order = [JOINTS_14.index(j) for j in POSE2SIM_MARKERS]
    for read, suffix in ((read_trc, "trc"), (read_c3d, "c3d"), (read_csv, "csv")):
        back = read(out / f"poses3d.{suffix}")
        assert back.names == tuple(POSE2SIM_MARKERS.values()) and back.rate == 25.0
        assert back.frames.tolist() == [0, 1, 2, 3]
        np.testing.assert_array_equal(np.isnan(back.positions), np.isnan(joints[:, order]))
        ok = np.isfinite(joints[:, order])
        assert np.max(np.abs(back.positions[ok] - joints[:, order][ok])) < ROUND_TRIP_M
    # C3D read by the library itself: millimetres, TRC axes (Y up = world z)
    c3d = ezc3d.c3d(str(out / "poses3d.c3d"))
    pts = c3d["data"]["points"]
    k = POSE2SIM_MARKERS and list(POSE2SIM_MARKERS).index("head")
    assert abs(pts[1, k, 0] / 1000.0 - joints[0, JOINTS_14.index("head"), 2]) < ROUND_TRIP_M
    filt = read_c3d(out / "poses3d_filt_butterworth.c3d")
    assert filt.metadata["filter"] == "butterworth low-pass, zero-phase, order 4, cut-off 6 Hz"
    assert "# filter: butterworth low-pass, zero-phase, order 4, cut-off 6 Hz" in \
        (out / "poses3d_filt_butterworth.csv").read_text()
    ok = np.isfinite(p3["joints_filtered"][:, order])
    assert np.max(np.abs(read_trc(out / "poses3d_filt_butterworth.trc").positions[ok]
                         - p3["joints_filtered"][:, order][ok])) < ROUND_TRIP_M
    meta = json.loads((out / "poses3d.json").read_text())
    assert meta["filter_cutoff_hz"] == 6.0 and meta["frame_rate_hz"] == 25.0 and meta["camera_matching"] == "by name"
    assert "poses3d_filt_butterworth.trc" in meta["files"]


def test_bad_inputs_are_named(tmp_path, capsys):
    _, _, kp_root = make_scene(tmp_path, n_frames=2)
    common = ["--calibration", tmp_path / "calib.toml", "--keypoints", kp_root, "--no-recording", "--quiet",
              "--format", "body_25b"]
    assert run(common + ["--out", tmp_path / "o1", "--fps", 10, "--filter-cutoff", 6]) == 2
    assert "--filter-cutoff" in capsys.readouterr().err
    f = kp_root / "cam02_json" / "cam02.0000.json"
    data = json.loads(f.read_text())
    data["people"][0]["pose_keypoints_2d"][2] = -1.0
    f.write_text(json.dumps(data))
    assert run(common + ["--out", tmp_path / "o2"]) == 2
    err = capsys.readouterr().err
    assert "cam02.0000.json" in err and "confidences >= 0" in err
    (kp_root / "cam03_json").rename(kp_root / "cam05_json")
    assert run(common + ["--out", tmp_path / "o3"]) == 2
    err = capsys.readouterr().err
    assert "cam05_json" in err and "cam_03" in err


#: Pose2Sim demo, balancing trial, first frames with default options: median distance to
#: Pose2Sim's own .trc over the limb joints (the existing demo test's bound).
DEMO_VS_POSE2SIM_M = 0.06


@pytest.mark.realdata
def test_pose2sim_trial_folder_read_as_it_is(tmp_path, capsys):
    root = Path(os.environ.get("TOOLKIT_REALDATA", REPO_ROOT.parent / "shared" / "realdata")) / "pose2sim_demo"
    trial = root / "S00_P00_SingleParticipant" / "S00_P00_T01_BalancingTrial"
    if not trial.is_dir():
        pytest.skip(f"real data not found at {root}")
    out = tmp_path / "demo"
    assert run(["--keypoints", trial, "--out", out, "--max-frames", 5, "--no-recording", "--quiet"]) == 0
    printed = capsys.readouterr().out
    assert "60 fps (Pose2Sim Config.toml)" in printed and "format body_25b" in printed
    ours = read_trc(out / "poses3d.trc")
    theirs = read_trc(next((trial / "pose-3d").glob("*_0-100.trc")))
    assert ours.rate == theirs.rate == 60.0 and ours.frames.tolist() == theirs.frames[:5].tolist()
    names = [n for n in ours.names if n not in ("Head", "Neck")]
    d = [np.linalg.norm(ours.positions[:, ours.names.index(n)] - theirs.positions[:5, theirs.names.index(n)], axis=-1)
         for n in names]
    assert np.median(d) < DEMO_VS_POSE2SIM_M
    meta = json.loads((out / "poses3d.json").read_text())
    assert meta["calibration"].endswith("Calib_qualisys.toml") and meta["keypoints"].endswith("pose-associated")
