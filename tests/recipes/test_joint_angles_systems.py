"""recipes/joint_angles.py end to end on the output of other systems' runs: depth tracking, free viewpoint
with several people (``people3d.npz``)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from recipes import joint_angles as recipe
from toolkit.biomech.angles import joint_angles
from toolkit.biomech.files import read_angles_csv
from toolkit.biomech.mapping import joints_to_points
from toolkit.biomech.synthetic import posed_points, random_rotation, smooth_motion
from toolkit.skeleton import JOINTS_14

#: angles.csv keeps 4 decimals.
CSV_DEG = 1e-3
#: Depth run: knee flexion from the tracked skeleton against the same angle from the true joints, RMS
#: over the frames, degrees.  Measured 5.7 / 13.7 (left / right; the tracker's MPJPE 24 mm on this walk):
#: a joint 45 mm off (the depth recipe's bound) turns a 0.4 m segment by 6.5 degrees, and a knee angle has
#: three joints and two segments.  The angle's accuracy is the tracker's; this checks the chain end to end.
DEPTH_KNEE_RMS_DEG = 20.0
#: The people of the synthetic free-viewpoint run.
PEOPLE = ("person_0", "person_1")


@pytest.fixture(scope="module")
def depth_run(tmp_path_factory):
    """A depth-tracking run (recipes/depth_tracking.py) on 8 rendered frames, with the true joints."""
    from recipes import depth_tracking
    from toolkit.anthropometry.proportions import BodyProportions
    from toolkit.body.model import BodyModel
    from toolkit.motion import generate_motion
    from toolkit.synthetic.depth_sensor import DepthCameraSpec, render_depth_camera

    root = tmp_path_factory.mktemp("depth_angles")
    props = BodyProportions.sample(1.72, 11)
    model = BodyModel.sample(props, 11, detail=0.5)
    J = generate_motion("walk", props, 8, 30.0, rng=11)
    render_depth_camera(root / "ds", DepthCameraSpec(resolution=(320, 240), environment="floor"), model, J, rng=11)
    out = root / "track"
    assert depth_tracking.main([str(root / "ds"), "--out", str(out), "--quiet", "--no-recording"]) == 0
    return out, J


def test_depth_run_to_angles_bvh_and_gltf(depth_run, tmp_path):
    track, truth_joints = depth_run
    out = tmp_path / "angles"
    assert recipe.main([str(track), "--out", str(out), "--fps", "30", "--bvh", "--gltf", "--no-recording"]) == 0
    a = read_angles_csv(out / "angles.csv")
    np.testing.assert_allclose(a.time, np.arange(8) / 30.0, atol=1e-6)
    assert {"l_knee_flexion", "r_hip_flexion", "l_elbow_flexion", "r_shoulder_abduction"} <= set(a.names)
    assert "l_ankle_dorsiflexion" not in a.names          # the depth skeleton has no toe
    summary = json.loads((out / "summary.json").read_text())
    assert summary["system"] == "depth" and summary["frames"] == 8
    truth = joint_angles(joints_to_points(truth_joints, JOINTS_14), 30.0)
    for name in ("l_knee_flexion", "r_knee_flexion"):
        tracked = np.isfinite(a[name])
        assert tracked.sum() >= 6, name
        rms = np.sqrt(np.mean((a[name] - truth[name])[tracked] ** 2))
        assert rms < DEPTH_KNEE_RMS_DEG, (name, rms)
    for f in ("motion.bvh", "motion.glb"):
        assert (out / f).stat().st_size > 0
    # without a frame rate (skeleton.npz has none) the run says what is missing
    assert recipe.main([str(track), "--out", str(tmp_path / "nofps"), "--no-recording"]) == 2


def _people_run(tmp_path):
    """A free-viewpoint run folder with two people, written by the pipeline's own people3d.npz writer."""
    from toolkit.pipeline.free_viewpoint import _PeopleJoints

    rng = np.random.default_rng(31)
    n = 12
    truths, joints = {}, {}
    for k, name in enumerate(PEOPLE):
        truth = {a: v for a, v in smooth_motion(n, rng).items() if a.endswith("flexion")}
        pts = posed_points(truth, n, body=random_rotation(rng), origin=(1.2 * k, 0.0, 1.0))
        truths[name], joints[name] = truth, np.stack([pts[j] for j in JOINTS_14], 1)
    records = [{"frame": t, "people": [{"name": p, "status": "ok", "joints": joints[p][t].tolist()}
                                       for p in PEOPLE]} for t in range(n)]
    folder = tmp_path / "fvv"
    folder.mkdir()
    people = _PeopleJoints(n)
    for r in records:
        people.add(r)
    assert people.write(folder)["names"] == list(PEOPLE)
    # the main person's poses3d.npz, as the recipe writes it besides people3d.npz
    np.savez(folder / "poses3d.npz", joints=joints[PEOPLE[0]], names=np.array(JOINTS_14))
    return folder, truths


def test_free_viewpoint_people_one_person_and_every_person(tmp_path):
    folder, truths = _people_run(tmp_path)
    out = tmp_path / "one"
    assert recipe.main([str(folder), "--out", str(out), "--fps", "25", "--person", PEOPLE[1], "--no-recording"]) == 0
    a = read_angles_csv(out / "angles.csv")
    for name in ("l_knee_flexion", "r_hip_flexion", "l_elbow_flexion"):
        np.testing.assert_allclose(a[name], truths[PEOPLE[1]][name], atol=CSV_DEG, err_msg=name)
    assert json.loads((out / "summary.json").read_text())["person"] == PEOPLE[1]
    every = tmp_path / "every"
    assert recipe.main([str(folder / "people3d.npz"), "--out", str(every), "--fps", "25", "--person", "all",
                        "--no-recording"]) == 0
    for p in PEOPLE:
        a = read_angles_csv(every / p / "angles.csv")
        np.testing.assert_allclose(a["r_knee_flexion"], truths[p]["r_knee_flexion"], atol=CSV_DEG, err_msg=p)


def test_free_viewpoint_people_without_a_valid_person_lists_them(tmp_path, capsys):
    folder, truths = _people_run(tmp_path)
    assert recipe.main([str(folder), "--out", str(tmp_path / "x"), "--fps", "25", "--person", "nobody",
                        "--no-recording"]) == 2
    err = capsys.readouterr().err
    assert "people3d.npz" in err and all(p in err for p in PEOPLE) and "nobody" in err
    assert recipe.main([str(folder / "people3d.npz"), "--out", str(tmp_path / "y"), "--fps", "25",
                        "--no-recording"]) == 2
    err = capsys.readouterr().err
    assert all(p in err for p in PEOPLE) and "--person" in err
    # the folder alone: the main person (poses3d.npz), with a note naming the others
    out = tmp_path / "main"
    assert recipe.main([str(folder), "--out", str(out), "--fps", "25", "--no-recording"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["people"] == list(PEOPLE) and summary["person"] is None
    assert any("--person" in n for n in summary["notes"])
    a = read_angles_csv(out / "angles.csv")
    np.testing.assert_allclose(a["l_knee_flexion"], truths[PEOPLE[0]]["l_knee_flexion"], atol=CSV_DEG)
