"""Inputs that used to end silently wrong: each now gives the right result or says what went wrong.

A flat wall in front of a depth camera, a spurious detection far outside the capture volume, a
damaged video, and a full disk during a free-viewpoint run's final writes.
"""

from __future__ import annotations

import json
import shutil
from dataclasses import replace

import numpy as np
import pytest

from tests.reliability.test_interruptions import advertised, full_disk_at, fv_config, tiny, verify  # noqa: F401
from toolkit.errors import InputError


@pytest.mark.parametrize("size", [(64, 48), (320, 240)])
def test_a_flat_wall_is_never_tracked_as_a_person(tmp_path, capsys, size):
    """A flat wall was tracked as a person: at 320 x 240 its frames became 'tracking' after four, and
    every frame's joints were written.  Now no frame of a wall has joints, each says why, and so does
    the summary."""
    from recipes import depth_tracking
    from toolkit.depth import STATE_NAMES

    w, h = size
    frames = tmp_path / "frames"
    frames.mkdir()
    for i in range(8):
        np.full((h, w), 2000, "<u2").tofile(frames / f"depth-{i}")   # every pixel 2 m away: a wall
    assert depth_tracking.main([str(frames), "--out", str(tmp_path / "o"), "--size", str(w), str(h), "--quiet",
                                "--no-recording"]) == 0
    z = np.load(tmp_path / "o" / "skeleton.npz")
    assert (z["state"] == STATE_NAMES.index("lost")).all()
    assert np.isnan(z["joints"]).all() and not z["observed"].any()
    assert all(r == "no person: a flat surface" for r in z["reason"].tolist())
    out = capsys.readouterr().out
    assert "8 lost" in out and "8 frames without a person (a flat surface)" in out


def test_a_person_in_front_of_a_wall_is_still_tracked():
    """The flat-surface check leaves a person in front of the walls of a studio with joints in every frame."""
    from tests.depth.conftest import make_sequence
    from toolkit.depth import LOST, DepthTracker, track_sequence

    seq = make_sequence("wave", 8, seed=5, environment="studio")[0]
    res = track_sequence(DepthTracker(seq.camera, True), seq.depth)
    assert (res.states != LOST).all() and np.isfinite(res.joints).all()


def test_a_spurious_detection_far_outside_the_volume_is_not_the_person(tmp_path):
    """A more confident detection 9 m away from the capture volume was chosen as the person (9 m off)."""
    from tests.recipes.test_pose_from_keypoints import BODY_25B, JOINTS_14, SOURCE_OF, make_scene
    from tests.reliability.test_no_output_lost import kp_args, recipe

    rig, poses, kp = make_scene(tmp_path, n_frames=10)
    far = poses + np.array([-9.0, 0.0, 0.0])                          # a bystander beyond the cameras
    seen = 0
    for c, cam in enumerate(rig):
        for t in range(9):
            f = kp / f"cam{c + 1:02d}_json" / f"cam{c + 1:02d}.{t:04d}.json"
            data = json.loads(f.read_text())
            if not data["people"][0] or (cam.depth_of(far[t]) <= 0).any() \
                    or not cam.in_image(cam.project(far[t])).all():
                continue
            k = np.zeros((25, 3))
            uv = cam.project(far[t])
            for name, joint in SOURCE_OF.items():
                k[BODY_25B.index(name)] = [*uv[JOINTS_14.index(joint)], 1.0]   # more confident than the person
            data["people"].insert(0, {"person_id": [-1], "pose_keypoints_2d": k.ravel().tolist()})
            f.write_text(json.dumps(data))
            seen += 1
    assert seen >= 9                                                  # the set-up: the bystander is detected
    assert recipe("pose_from_keypoints")(kp_args(tmp_path, kp, tmp_path / "o")) == 0
    J = np.load(tmp_path / "o" / "poses3d.npz")["joints"][:9]
    assert np.linalg.norm(J - poses[:9], axis=-1).max() < 0.05


def test_a_damaged_video_is_said_in_the_summary(tiny, tmp_path):  # noqa: F811
    """Damaged frame data gave a run 'finished' with no pose and nothing said; the summary now counts the
    frames without a result and why."""
    import toolkit.pipeline.free_viewpoint as fv

    shutil.copytree(tiny, tmp_path / "ds")
    video = tmp_path / "ds" / "videos" / "cam00.mp4"
    data = bytearray(video.read_bytes())
    n = len(data)
    data[n // 3: 2 * (n // 3)] = bytes(n // 3)                          # a third of the file zeroed
    video.write_bytes(bytes(data))
    r = fv.run(replace(fv_config(), max_frames=2), dataset=tmp_path / "ds", out=tmp_path / "o", log=None)
    status = np.load(tmp_path / "o" / "poses3d.npz")["status"].tolist()
    assert status.count("ok") < 2
    failed = {k: v for k, v in r.metrics["status"].items() if k != "ok"}
    assert "frames without a result: " + "; ".join(f"{v} {k}" for k, v in failed.items()) \
        in "\n".join(fv.summary_lines(r))


def test_a_full_disk_at_the_final_writes_is_resumed(tiny, tmp_path, monkeypatch):  # noqa: F811
    """A full disk during the final writes left poses3d.npz / metrics.json unwritten; the frames stay, the
    recording opens, and the rerun writes them."""
    import toolkit.pipeline.free_viewpoint as fv

    out, config = tmp_path / "o", replace(fv_config(), max_frames=2)
    with monkeypatch.context() as m:
        full_disk_at(m, "metrics.json")
        with pytest.raises(InputError, match="metrics.json"):
            fv.run(config, dataset=tiny, out=out, log=None)
    assert len(list((out / "frames").glob("*.json"))) == 2 and not (out / "metrics.json").exists()
    verify(out / "recording.rrd")
    r = fv.run(config, dataset=tiny, out=out, log=None)
    assert r.complete and r.processed == 0 and (out / "metrics.json").is_file()
    assert np.isfinite(np.load(out / "poses3d.npz")["joints"]).all()
    verify(*advertised("\n".join(fv.summary_lines(r))))


def test_a_run_without_any_pose_is_a_failure(tiny, tmp_path, monkeypatch, capsys):  # noqa: F811
    """A free-viewpoint run in which no frame had a 3D pose exited 0; it now exits 2 with a one-line
    reason, while a run with a pose in some frames exits 0 and names the frames without one."""
    import toolkit.pipeline.free_viewpoint as fv
    from recipes import free_viewpoint
    from toolkit.io import Dataset
    from toolkit.pipeline.frame import STATUS_BEHIND

    with Dataset.open(tiny) as ds:
        centre = ds.rig[0].center
    real = fv._Stage1.estimates

    def mirrored(est):  # stage 1's joints behind the first camera, where a flipped calibration puts them
        return replace(est, joints3d=2 * centre - np.asarray(est.joints3d, float))

    def flipping(frames_flipped):
        def estimates(self, frames):
            for est, masks in real(self, frames):
                if est.frame in frames_flipped:
                    est = replace(est, estimates=[mirrored(e) for e in est.estimates]) \
                        if hasattr(est, "estimates") else mirrored(est)
                yield est, masks
        return estimates

    args = [str(tiny), "--workers", "1", "--no-baselines", "--max-frames", "2", "--quiet"]
    monkeypatch.setattr(fv._Stage1, "estimates", flipping({0, 1}))
    assert free_viewpoint.main(args + ["--out", str(tmp_path / "none")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: no frame has a 3D pose") and STATUS_BEHIND in err[0]
    monkeypatch.setattr(fv._Stage1, "estimates", flipping({1}))
    assert free_viewpoint.main(args + ["--out", str(tmp_path / "some")]) == 0
    out = capsys.readouterr()
    assert f"frames without a result: 1 {STATUS_BEHIND}" in out.out and "frames 1 (" in out.out
    assert "error" not in out.err


@pytest.mark.parametrize("view", [0, 1, 2])
def test_a_short_sequence_with_a_spurious_detection_keeps_its_person(tmp_path, view):
    """Three frames (the person in the first two) and one bystander detected in one view gave 0 estimates:
    the tracking kept only people seen in every frame of a sequence shorter than its minimum track, and
    nobody is seen in the last one.  The person is now found in both frames; the bystander is not the person."""
    from tests.recipes.test_pose_from_keypoints import BODY_25B, JOINTS_14, SOURCE_OF, make_scene
    from tests.reliability.test_no_output_lost import kp_args, recipe

    rig, poses, kp = make_scene(tmp_path, n_frames=3)             # frame 2: nobody in any view
    cam, t = rig[view], 0
    f = kp / f"cam{view + 1:02d}_json" / f"cam{view + 1:02d}.{t:04d}.json"
    data = json.loads(f.read_text())
    k = np.zeros((25, 3))
    uv = cam.project(poses[t] + np.array([0.8, -0.6, 0.0]))           # a bystander beside the person
    for name, joint in SOURCE_OF.items():
        k[BODY_25B.index(name)] = [*uv[JOINTS_14.index(joint)], 0.95]  # more confident than the person
    data["people"].append({"person_id": [-1], "pose_keypoints_2d": k.ravel().tolist()})
    f.write_text(json.dumps(data))
    assert recipe("pose_from_keypoints")(kp_args(tmp_path, kp, tmp_path / "o")) == 0
    J = np.load(tmp_path / "o" / "poses3d.npz")["joints"]
    assert np.isfinite(J[:2]).all() and np.isnan(J[2]).all()
    assert np.linalg.norm(J[:2] - poses[:2], axis=-1).max() < 0.05


def test_a_run_where_only_other_people_are_drawn_is_not_a_failure(tmp_path):
    """With several people the first one (``poses3d.npz``) may have no pose in any frame while the others
    are drawn (a player the silhouettes lost): that run went through, it is no failure."""
    from types import SimpleNamespace

    from toolkit.pipeline.free_viewpoint import run_failure

    def result(drawn):
        return SimpleNamespace(stopped=None, finished=4, frames=4, out=tmp_path,
                               metrics={"status": {"no 3D pose from stage 1": 4},
                                        "people": {"frames_drawn": drawn}})

    assert run_failure(result({"person_0": 0, "person_1": 4})) is None
    assert "no frame has a 3D pose" in run_failure(result({"person_0": 0, "person_1": 0}))
    assert "no frame has a 3D pose" in run_failure(result({}))
