"""recipes/pose_from_keypoints.py with several people: --multi-person, and the single person chosen."""

from __future__ import annotations

import importlib
import json
import os
from pathlib import Path

import numpy as np
import pytest

from toolkit.io import write_calibration
from toolkit.skeleton import JOINTS_14
from toolkit.skeleton.mappings import BODY_25B
from toolkit.synthetic.crowd import detect_crowd, make_crowd, score_people

REPO_ROOT = Path(__file__).resolve().parents[2]
#: BODY_25B keypoints that carry our 14 joints (head = mean of the ears, neck = UpperNeck).
SOURCE_OF = {"LEar": "head", "REar": "head", "UpperNeck": "neck",
             **{f"{s}{n.capitalize()}": f"{s.lower()}_{n}" for s in ("L", "R")
                for n in ("shoulder", "elbow", "wrist", "hip", "knee", "ankle")}}
#: Per person MPJPE with 0.5 px jitter, no bias, exact calibration (studio ring at 5-6.5 m,
#: 1280 x 720): measured 3-6 mm.
MULTI_MPJPE_M = 0.015
#: Pose2Sim demo: the person found in the raw pose/ folders against the single-person result on
#: pose-associated/ (Pose2Sim's own association), median joint distance (measured 0.0 mm: the
#: same detections, the bystander left out).
DEMO_MULTI_VS_SINGLE_M = 0.005
N_FRAMES = 8


def run(argv):
    mod = importlib.import_module("recipes.pose_from_keypoints")
    return mod.main([str(a) for a in argv])


def write_crowd(root: Path, seed=0, confident_bystander=True):
    """Two people (one enters late) and a bystander seen by one camera, as OpenPose BODY_25B files."""
    scene = make_crowd(2, 1, 3, N_FRAMES, 25.0, 0.0, rng=seed)
    det = detect_crowd(scene, rng=seed, bias_px=0.0, jitter_px=0.5, miss=0.0, swap=0.0, occlusion=0.0)
    write_calibration(root / "calib.toml", scene.measured_rig)
    for v in range(len(scene.rig)):
        folder = root / "keypoints" / f"cam{v:02d}_json"
        folder.mkdir(parents=True)
        for t in range(N_FRAMES):
            people = []
            for d, b in zip(det.detections[t][v], det.identity[t][v]):
                kp = np.zeros((25, 3))
                conf = 0.95 if scene.roles[b] == "bystander" and confident_bystander else 0.6
                for name, joint in SOURCE_OF.items():
                    kp[BODY_25B.index(name)] = [*d[JOINTS_14.index(joint), :2], conf]
                people.append({"person_id": [-1], "pose_keypoints_2d": kp.ravel().tolist()})
            (folder / f"cam{v:02d}.{t:04d}.json").write_text(json.dumps({"version": 1.3, "people": people}))
    return scene, det


def test_multi_person_writes_each_person(tmp_path, capsys):
    scene, det = write_crowd(tmp_path)
    out = tmp_path / "out"
    assert run(["--calibration", tmp_path / "calib.toml", "--keypoints", tmp_path / "keypoints", "--out", out,
                "--multi-person", "--quiet", "--export", "none"]) == 0
    folders = sorted(p.name for p in out.iterdir() if p.is_dir())
    assert folders == ["person_0", "person_1"]  # the bystander is not a person
    people = json.loads((out / "people.json").read_text())["people"]
    assert [p["person"] for p in people] == folders
    est = []
    for name in folders:
        p3 = np.load(out / name / "poses3d.npz")
        assert p3["joints"].shape == (N_FRAMES, 14, 3)
        assert list(p3["names"]) == list(JOINTS_14)
        for f in ("offsets.npz", "flips.npz", "poses2d.npz", "poses3d.json", "anthropometry.txt"):
            assert (out / name / f).is_file()
        est.append(p3["joints"])
    score = score_people(np.array(est), scene, det)
    assert (score.mpjpe_m < MULTI_MPJPE_M).all()
    assert (score.switches == 0).all() and score.false_people == 0
    # the late person is NaN before it enters
    late = scene.people[np.argmax([np.isnan(scene.joints[p, :, 0, 0]).sum() for p in scene.people])]
    absent = np.isnan(scene.joints[late, :, 0, 0])
    if absent.any():
        k = int(np.argmin([np.nanmedian(np.linalg.norm(e - scene.joints[late], axis=-1)) for e in est]))
        assert np.isnan(est[k][absent]).all()
    assert (out / "recording.rrd").stat().st_size > 0
    assert "2 people found" in capsys.readouterr().out


def test_single_person_is_the_one_cameras_agree_on(tmp_path):
    """Without --multi-person: not the most confident detection (the bystander), the person most cameras see."""
    scene, _ = write_crowd(tmp_path)
    out = tmp_path / "one"
    assert run(["--calibration", tmp_path / "calib.toml", "--keypoints", tmp_path / "keypoints", "--out", out,
                "--quiet", "--export", "none", "--no-recording"]) == 0
    joints = np.load(out / "poses3d.npz")["joints"]
    first = scene.joints[scene.people[0]]  # present in every frame
    assert np.isfinite(joints).all()
    assert np.mean(np.linalg.norm(joints - first, axis=-1)) < MULTI_MPJPE_M


def test_observer_colours_each_person():
    from toolkit.observe import PrefixedObserver, RecordingObserver

    rec = RecordingObserver()
    obs = PrefixedObserver(rec, "person_1", (1, 2, 3))
    obs.report("joints3d", joints=np.zeros((14, 3)), name="multiview/joints3d")
    obs.report("rig", rig=())
    obs.report("points3d", points=np.zeros((2, 3)))
    (k1, d1), (k2, d2), (k3, d3) = rec.reports
    assert d1["name"] == "person_1/multiview/joints3d" and d1["color"] == (1, 2, 3)
    assert "name" not in d2 and d3["name"] == "person_1/points3d"


@pytest.mark.realdata
def test_pose2sim_demo_raw_detections_give_one_person(tmp_path, capsys):
    """The raw pose/ folders hold a bystander in the background of two views: one person found."""
    root = Path(os.environ.get("TOOLKIT_REALDATA", REPO_ROOT.parent / "shared" / "realdata")) / "pose2sim_demo"
    trial = root / "S00_P00_SingleParticipant" / "S00_P00_T01_BalancingTrial"
    if not trial.is_dir():
        pytest.skip(f"real data not found at {root}")
    calib = root / "S00_Calibration" / "Calib_qualisys.toml"
    common = ["--calibration", calib, "--max-frames", 12, "--quiet", "--export", "none", "--no-recording"]
    assert run(["--keypoints", trial / "pose", "--out", tmp_path / "multi", "--multi-person", *common]) == 0
    assert sorted(p.name for p in (tmp_path / "multi").iterdir() if p.is_dir()) == ["person_0"]
    assert run(["--keypoints", trial / "pose-associated", "--out", tmp_path / "single", *common]) == 0
    multi = np.load(tmp_path / "multi" / "person_0" / "poses3d.npz")["joints"]
    single = np.load(tmp_path / "single" / "poses3d.npz")["joints"]
    assert np.isfinite(multi).all()
    assert np.nanmedian(np.linalg.norm(multi - single, axis=-1)) < DEMO_MULTI_VS_SINGLE_M


def test_rerun_observer_draws_a_person_in_its_colour(tmp_path):
    from toolkit.skeleton import SKELETON_14
    from toolkit.viz import RerunObserver

    with RerunObserver(path=tmp_path / "r.rrd") as obs:
        obs.report("skeleton", skeleton=SKELETON_14)
        obs.report("joints3d", joints=np.zeros((14, 3)), name="person_0/joints3d", skeleton=SKELETON_14,
                   color=(1, 2, 3), frame=0)
        obs.report("joints3d", joints=np.zeros((14, 3)), name="person_0/joints3d", skeleton=SKELETON_14,
                   color=(1, 2, 3), frame=1)
        ids = obs.skeleton_class_ids
    assert len(ids) == 2 and ids[SKELETON_14.name] != ids[f"{SKELETON_14.name} (1, 2, 3)"]
