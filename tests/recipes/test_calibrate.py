"""End-to-end tests of recipes/calibrate.py: intrinsics from rendered boards, extrinsics from scene points and
from people's keypoints, clear errors."""

from __future__ import annotations

import importlib
import json
from pathlib import Path

import cv2
import numpy as np
import pytest

from toolkit.calibration.boards import Board
from toolkit.calibration.extrinsics import similarity_align
from toolkit.cameras import Camera, Rig
from toolkit.io.calibration import read_calibration, write_calibration
from toolkit.skeleton import JOINTS_14
from toolkit.skeleton.mappings import BODY_25B
from toolkit.synthetic.boards import board_pose, people_sequence, pixel_rays, random_board_poses, render_checkerboard

#: Rendered boards: relative focal error.
FOCAL_TOL = 0.01
#: Scene points / keypoints with 0.5 px noise: camera centres, metres.
CENTRE_TOL_M = 0.03
#: BODY_25B keypoints that carry our 14 joints (head = mean of the ears, neck = UpperNeck).
SOURCE_OF = {"LEar": "head", "REar": "head", "UpperNeck": "neck",
             **{f"{s}{n.capitalize()}": f"{s.lower()}_{n}" for s in ("L", "R")
                for n in ("shoulder", "elbow", "wrist", "hip", "knee", "ankle")}}


def load_recipe():
    return importlib.import_module("recipes.calibrate")


def rig(n=3, size=(640, 480)) -> Rig:
    return Rig(tuple(Camera.look_at(f"cam_{i + 1:02d}", [4 * np.cos(a), 4 * np.sin(a), 1.8 + 0.2 * i], [0, 0, 1.0],
                                    size=size, focal_px=560.0)
                     for i, a in enumerate(np.radians([0, 100, 210][:n]))))


def intrinsics_rig(r: Rig) -> Rig:
    return Rig(tuple(c.replace(cam_from_world=np.eye(4)) for c in r))


def test_intrinsics_command_on_rendered_boards(tmp_path, capsys):
    board = Board("checkerboard", 5, 7, 0.03)
    cam = Camera.look_at("x", [0, 0, 0], [0, 1, 0], size=(320, 240), focal_px=400.0, dist=[-0.1, 0.02, 0, 0, 0])
    rays = pixel_rays(cam)
    for c in (1, 2):
        folder = tmp_path / "intr" / f"int_cam{c:02d}_img"
        folder.mkdir(parents=True)
        for i, T in enumerate(random_board_poses(cam, board, 6, np.random.default_rng(c), distance=(0.4, 0.8))):
            cv2.imwrite(str(folder / f"v{i}.png"), render_checkerboard(cam, board, T, rays=rays))
    out = tmp_path / "intrinsics.toml"
    rc = load_recipe().main(["intrinsics", str(tmp_path / "intr"), "--board", "checkerboard", "--corners", "5,7",
                             "--square-mm", "30", "--out", str(out), "--no-recording"])
    assert rc == 0
    got = read_calibration(out)
    assert got.names == ["cam_01", "cam_02"]
    for c in got:
        assert abs(c.K[0, 0] / 400.0 - 1) < FOCAL_TOL and c.size == (320, 240)
    report = json.loads(out.with_suffix(".json").read_text())
    assert set(report["cameras"]) == {"cam_01", "cam_02"}
    assert "cam_01" in capsys.readouterr().out


def test_intrinsics_command_says_the_board_size_is_wrong(tmp_path, capsys):
    board = Board("checkerboard", 5, 7, 0.03)
    cam = Camera.look_at("x", [0, 0, 0], [0, 1, 0], size=(320, 240), focal_px=400.0)
    folder = tmp_path / "cam01"
    folder.mkdir()
    T = random_board_poses(cam, board, 1, np.random.default_rng(0), distance=(0.4, 0.6), max_tilt_deg=15)[0]
    cv2.imwrite(str(folder / "v.png"), render_checkerboard(cam, board, T))
    rc = load_recipe().main(["intrinsics", str(tmp_path), "--board", "checkerboard", "--corners", "6,7",
                             "--square-mm", "30", "--out", str(tmp_path / "i.toml"), "--no-recording"])
    assert rc == 2
    err = capsys.readouterr().err
    assert "5x7 inner corners" in err and "not 6x7 as declared" in err


def test_intrinsics_command_bad_corners_argument(tmp_path, capsys):
    rc = load_recipe().main(["intrinsics", str(tmp_path), "--board", "checkerboard", "--corners", "four",
                             "--square-mm", "30", "--out", str(tmp_path / "i.toml")])
    assert rc == 2 and "--corners" in capsys.readouterr().err


def test_extrinsics_command_from_scene_points(tmp_path):
    truth = rig()
    write_calibration(tmp_path / "intrinsics.toml", intrinsics_rig(truth))
    rng = np.random.default_rng(1)
    X = rng.uniform([-2, -2, 0], [2, 2, 1.5], (10, 3))
    lines = ["camera,point,x,y,z,u,v"]
    for c, cam in enumerate(truth):
        uv = cam.project(X) + rng.normal(0, 0.5, (10, 2))
        lines += [f"{c + 1:02d}cam,P{i},{X[i, 0]},{X[i, 1]},{X[i, 2]},{uv[i, 0]},{uv[i, 1]}" for i in range(10)]
    (tmp_path / "points.csv").write_text("\n".join(lines) + "\n")
    out = tmp_path / "calibration.toml"
    rc = load_recipe().main(["extrinsics", "--intrinsics", str(tmp_path / "intrinsics.toml"), "--scene-points",
                             str(tmp_path / "points.csv"), "--out", str(out)])
    assert rc == 0
    got = read_calibration(out)
    assert np.linalg.norm(got.centers - truth.centers, axis=1).max() < CENTRE_TOL_M
    assert out.with_suffix(".rrd").is_file()


def write_openpose(root: Path, truth: Rig, joints: np.ndarray, rng, noise_px=0.5):
    for c, cam in enumerate(truth):
        folder = root / f"cam{c + 1:02d}_json"
        folder.mkdir(parents=True)
        for t in range(len(joints)):
            uv = cam.project(joints[t]) + rng.normal(0, noise_px, (14, 2))
            kp = np.zeros((25, 3))
            for name, joint in SOURCE_OF.items():
                kp[BODY_25B.index(name)] = [*uv[JOINTS_14.index(joint)], 0.9]
            (folder / f"cam{c + 1:02d}.{t:04d}.json").write_text(json.dumps(
                {"people": [{"person_id": [-1], "pose_keypoints_2d": kp.ravel().tolist()}]}))


def test_extrinsics_command_from_people(tmp_path, capsys):
    truth = rig()
    write_calibration(tmp_path / "intrinsics.toml", intrinsics_rig(truth))
    rng = np.random.default_rng(2)
    write_openpose(tmp_path / "kp", truth, people_sequence(40, rng, height=1.70)[0], rng)
    out = tmp_path / "calibration.toml"
    rc = load_recipe().main(["extrinsics", "--intrinsics", str(tmp_path / "intrinsics.toml"), "--keypoints",
                             str(tmp_path / "kp"), "--format", "body_25b", "--height-m", "1.70", "--out", str(out)])
    assert rc == 0
    got = read_calibration(out)
    s, R, t = similarity_align(got.centers, truth.centers)
    assert np.linalg.norm(s * got.centers @ R.T + t - truth.centers, axis=1).max() < CENTRE_TOL_M
    assert abs(s - 1) < 0.03  # metric from the stature
    assert np.all(got.centers[:, 2] > 1.0)  # above the floor fitted under the feet
    report = json.loads(out.with_suffix(".json").read_text())
    assert report["method"] == "people" and report["keypoints"]["matching"] == "by name"


def test_extrinsics_command_camera_mismatch_is_a_clear_error(tmp_path, capsys):
    truth = rig()
    write_calibration(tmp_path / "intrinsics.toml", intrinsics_rig(truth))
    rng = np.random.default_rng(3)
    write_openpose(tmp_path / "kp", Rig(truth.cameras[:2]), people_sequence(5, rng)[0], rng)
    rc = load_recipe().main(["extrinsics", "--intrinsics", str(tmp_path / "intrinsics.toml"), "--keypoints",
                             str(tmp_path / "kp"), "--out", str(tmp_path / "c.toml"), "--no-recording"])
    assert rc == 2
    assert "one per calibration camera" in capsys.readouterr().err


def test_help():
    with pytest.raises(SystemExit) as e:
        load_recipe().main(["--help"])
    assert e.value.code == 0


def test_extrinsics_command_from_board_images(tmp_path):
    board = Board("checkerboard", 4, 7, 0.10)  # 5 x 8 squares: the corner squares differ, so the order is fixed
    truth = Rig(tuple(Camera.look_at(f"cam_{i + 1:02d}", [2.5 * np.cos(a), 2.5 * np.sin(a), 1.6], [0, 0, 0.2],
                                     size=(400, 300), focal_px=350.0)
                      for i, a in enumerate(np.radians([10, 130, 250]))))
    write_calibration(tmp_path / "intrinsics.toml", intrinsics_rig(truth))
    rng = np.random.default_rng(4)
    poses = [board_pose([-0.3, -0.15, 0.0], facing=(0, 0, -1))]  # first view: on the floor, printed side up
    poses += [board_pose(rng.uniform([-0.4, -0.3, 0.1], [0.1, 0.1, 0.5]), rng.uniform(-25, 25, 2),
                         rng.uniform(-180, 180), facing=(0, 0, -1)) for _ in range(3)]
    for c, cam in enumerate(truth):
        folder = tmp_path / "ext" / f"ext_cam{c + 1:02d}_img"
        folder.mkdir(parents=True)
        rays = pixel_rays(cam)
        for v, T in enumerate(poses):
            cv2.imwrite(str(folder / f"v{v:02d}.png"), render_checkerboard(cam, board, T, rays=rays))
    out = tmp_path / "calibration.toml"
    rc = load_recipe().main(["extrinsics", "--intrinsics", str(tmp_path / "intrinsics.toml"), "--board-images",
                             str(tmp_path / "ext"), "--board", "checkerboard", "--corners", "4,7", "--square-mm",
                             "100", "--out", str(out)])
    assert rc == 0
    got = read_calibration(out)
    s, R, t = similarity_align(got.centers, truth.centers)
    assert np.linalg.norm(s * got.centers @ R.T + t - truth.centers, axis=1).max() < CENTRE_TOL_M
    assert abs(s - 1) < 0.01  # metric from the squares
    assert np.abs(got.centers[:, 2] - truth.centers[:, 2]).max() < CENTRE_TOL_M  # the first board is the floor
    report = json.loads(out.with_suffix(".json").read_text())
    assert report["method"] == "board" and not report["warnings"]


def test_pose2sim_participant_height_read_from_the_settings(tmp_path):
    a, b = tmp_path / "Config.toml", tmp_path / "trial.toml"
    a.write_text("[markerAugmentation]\nparticipant_height = 1.72 # m\n")
    b.write_text("[markerAugmentation]\n# participant_height = 1.80\n")
    from toolkit.io.pose2sim import participant_height

    h, where = participant_height([a, b])
    assert h == 1.72 and str(a) in where
    assert participant_height([b]) == (None, None)


def test_options_from_a_config_file_flags_win_unknown_keys_refused(tmp_path, capsys):
    recipe = load_recipe()
    cfg = tmp_path / "calib.toml"
    cfg.write_text('seed = 3\nformat = "body_25b"\n[board]\nkind = "charuco"\ncorners = [5, 7]\nsquare_mm = 40.0\n'
                   'marker_mm = 30.0\nmax_frames = 20\n')
    args = recipe.parser().parse_args(["extrinsics", "--intrinsics", "i.toml", "--board-images", "b", "--out", "o.toml",
                                       "--config", str(cfg), "--corners", "4,6", "--seed", "5", "--no-recording"])
    c = recipe.config_from_args(args)
    assert c.seed == 5 and c.format == "body_25b" and not c.recording               # the flag wins, the file stands
    assert c.board.kind == "charuco" and c.board.corners == (4, 6) and c.board.max_frames == 20
    b = c.board.board()
    assert (b.rows, b.cols, b.square, b.marker) == (4, 6, 0.04, 0.03)
    args = recipe.parser().parse_args(["extrinsics", "--intrinsics", "i.toml", "--scene-points", "p.csv", "--out",
                                       "o.toml", "--config", str(cfg)])
    assert recipe.config_from_args(args).board.corners == (5, 7)                 # a TOML array: a tuple
    cfg.write_text("[board]\nsquare = 40.0\n")
    rc = recipe.main(["intrinsics", str(tmp_path), "--config", str(cfg), "--out", str(tmp_path / "i.toml")])
    err = capsys.readouterr().err
    assert rc == 2 and f"{cfg}: board.square" in err and "square_mm" in err
    rc = recipe.main(["extrinsics", "--intrinsics", str(tmp_path / "i.toml"), "--keypoints", str(tmp_path),
                      "--height-m", "3.1", "--out", str(tmp_path / "c.toml")])
    assert rc == 2 and "--height-m" in capsys.readouterr().err
