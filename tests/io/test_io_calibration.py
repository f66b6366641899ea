"""Calibration files: TOML / YAML round trips, the Pose2Sim demo file, bad input."""

from __future__ import annotations

import json
import tomllib

import numpy as np
import pytest

from toolkit.cameras import Rig
from toolkit.errors import InputError
from toolkit.io.calibration import (
    calibration_toml_text,
    read_calibration,
    read_calibration_toml,
    write_calibration,
    write_calibration_yaml,
)

#: Round trips must reproduce every number to this (TOML floats are exact; the
#: rotation goes through a Rodrigues vector, which costs a few 1e-16).
ROUNDTRIP_TOL = 1e-12
#: The Pose2Sim demo's own triangulation projected through its calibration lands
#: 8-17 px (median per camera) from the OpenPose keypoints (PROVENANCE.md); a
#: transposed rotation gives 400-900 px.
POSE2SIM_MEDIAN_PX_TOL = 25.0

CALIB = "S00_Calibration/Calib_qualisys.toml"
TRIAL = "S00_P00_SingleParticipant/S00_P00_T01_BalancingTrial"
#: OpenPose BODY_25B keypoint index of Pose2Sim marker names.
BODY_25B = {
    "Nose": 0,
    "LShoulder": 5,
    "RShoulder": 6,
    "LElbow": 7,
    "RElbow": 8,
    "LWrist": 9,
    "RWrist": 10,
    "LHip": 11,
    "RHip": 12,
    "LKnee": 13,
    "RKnee": 14,
    "LAnkle": 15,
    "RAnkle": 16,
}


# ------------------------------------------------------------- round trips
@pytest.mark.parametrize("suffix", [".toml", ".yml", ".yaml"])
def test_round_trip(tmp_path, make_rig, rigs_equal, suffix):
    rig = make_rig(
        np.random.default_rng(1),
        n_cams=4,
        size=(1280, 720),
        names=["cam_01", "left cam", 'quote"d', "metadata_not"],
    )
    path = write_calibration(tmp_path / f"calib{suffix}", rig)
    back = read_calibration(path)
    rigs_equal(rig, back, ROUNDTRIP_TOL)
    assert [f.name for f in tmp_path.iterdir()] == [f"calib{suffix}"]  # no temporary left behind


def test_toml_is_deterministic_and_valid(tmp_path, make_rig):
    rig = make_rig(np.random.default_rng(2))
    write_calibration(
        tmp_path / "a.toml", rig, metadata={"adjusted": False, "error": 0.25, "tool": "x"}
    )
    write_calibration(
        tmp_path / "b.toml", rig, metadata={"adjusted": False, "error": 0.25, "tool": "x"}
    )
    a = (tmp_path / "a.toml").read_bytes()
    assert a == (tmp_path / "b.toml").read_bytes()
    doc = tomllib.loads(a.decode())
    assert list(doc) == rig.names + ["metadata"]
    assert doc["metadata"] == {"adjusted": False, "error": 0.25, "tool": "x"}
    assert doc["cam00"]["size"] == [64, 48] and doc["cam00"]["fisheye"] is False
    # metadata is ignored on reading
    assert read_calibration(tmp_path / "a.toml").names == rig.names


def test_toml_rotation_as_matrix_and_name_from_table(tmp_path, make_rig):
    cam = make_rig(np.random.default_rng(3), n_cams=1)[0]
    text = calibration_toml_text(Rig((cam,)))
    doc = tomllib.loads(text)
    table = doc[cam.name]
    del table["name"]
    table["rotation"] = cam.R.tolist()
    lines = ["[tablename]"] + [f"{k} = {json.dumps(v)}" for k, v in table.items()]
    (tmp_path / "m.toml").write_text("\n".join(lines) + "\n")
    back = read_calibration(tmp_path / "m.toml")
    assert back.names == ["tablename"]
    np.testing.assert_allclose(back[0].R, cam.R, atol=ROUNDTRIP_TOL)


def test_file_order_is_kept(tmp_path, make_rig):
    rig = make_rig(np.random.default_rng(4), n_cams=3, names=["z", "a", "m"])
    write_calibration(tmp_path / "c.toml", rig)
    assert read_calibration(tmp_path / "c.toml").names == ["z", "a", "m"]


# ------------------------------------------------------------- Pose2Sim demo
def test_pose2sim_file_loads(pose2sim_demo):
    rig = read_calibration(pose2sim_demo / CALIB)
    assert rig.names == ["cam_01", "cam_02", "cam_03", "cam_04"]
    assert all(c.size == (1088, 1920) for c in rig)  # written as floats 1088.0, 1920.0
    assert all(c.dist.shape == (4,) for c in rig)
    assert rig[0].K[0, 0] == 1681.244873046875
    np.testing.assert_array_equal(
        rig[0].t, [0.3211048899999996, 0.9563320600000009, 2.8907130499999996]
    )


def test_pose2sim_origin_projects_into_every_image(pose2sim_demo):
    """The lab origin (the treadmill) is 2.9-4.4 m in front of every camera and inside its image."""
    rig = read_calibration(pose2sim_demo / CALIB)
    for cam in rig:
        assert 2.5 < cam.depth_of(np.zeros(3)) < 5.0
        uv = cam.project(np.zeros(3))
        assert cam.in_image(uv), (cam.name, uv)


def _trc_frame(path, row):
    lines = path.read_text().splitlines()
    names = [n for n in lines[3].split("\t")[2:] if n]
    xyz = np.array(lines[5 + row].split("\t")[2:], dtype=float).reshape(-1, 3)
    return names, xyz[:, [2, 0, 1]]  # trc is Y up: world = (trc Z, trc X, trc Y)


def test_pose2sim_reprojection_matches_openpose(pose2sim_demo):
    rig = read_calibration(pose2sim_demo / CALIB)
    names, world = _trc_frame(
        pose2sim_demo / TRIAL / "pose-3d" / "S00_P00_T01_BalancingTrial_0-100.trc", 0
    )
    for i, cam in enumerate(rig):
        js = json.loads(
            (
                pose2sim_demo
                / TRIAL
                / "pose-associated"
                / f"cam0{i + 1}_json"
                / f"cam0{i + 1}.0000.json"
            ).read_text()
        )
        kp = np.array(js["people"][0]["pose_keypoints_2d"]).reshape(-1, 3)[:, :2]
        uv = cam.project(world)
        d = [np.linalg.norm(uv[names.index(n)] - kp[k]) for n, k in BODY_25B.items()]
        assert np.median(d) < POSE2SIM_MEDIAN_PX_TOL, (cam.name, np.median(d))


def test_pose2sim_round_trip(pose2sim_demo, tmp_path, rigs_equal):
    rig = read_calibration(pose2sim_demo / CALIB)
    rigs_equal(rig, read_calibration(write_calibration(tmp_path / "c.toml", rig)), ROUNDTRIP_TOL)


# ------------------------------------------------------------- bad input
GOOD_TABLE = """[cam_01]
name = "cam_01"
size = [ 64.0, 48.0]
matrix = [ [ 50.0, 0.0, 31.5], [ 0.0, 50.0, 23.5], [ 0.0, 0.0, 1.0]]
distortions = [ 0.01, 0.0, 0.0, 0.0]
rotation = [ 0.1, 0.2, 0.3]
translation = [ 0.0, 0.0, 3.0]
fisheye = false
"""


def _replace(field, value):
    return (
        "\n".join(
            f"{field} = {value}" if line.startswith(f"{field} =") else line
            for line in GOOD_TABLE.splitlines()
        )
        + "\n"
    )


BAD_TOML = {
    "missing matrix": (
        "\n".join(ln for ln in GOOD_TABLE.splitlines() if not ln.startswith("matrix")),
        "[cam_01].matrix",
    ),
    "matrix 2x3": (_replace("matrix", "[[50.0, 0.0, 31.5], [0.0, 50.0, 23.5]]"), "[cam_01].matrix"),
    "matrix not numbers": (_replace("matrix", '"K"'), "[cam_01].matrix"),
    "three distortions": (_replace("distortions", "[0.1, 0.0, 0.0]"), "[cam_01].distortions"),
    "nan translation": (_replace("translation", "[0.0, nan, 3.0]"), "[cam_01].translation"),
    "inf in matrix": (
        _replace("matrix", "[[inf, 0.0, 31.5], [0.0, 50.0, 23.5], [0.0, 0.0, 1.0]]"),
        "[cam_01].matrix",
    ),
    "rotation of 2": (_replace("rotation", "[0.1, 0.2]"), "[cam_01].rotation"),
    "non-rotation matrix": (
        _replace("rotation", "[[1.0, 0.0, 0.0], [0.0, 2.0, 0.0], [0.0, 0.0, 1.0]]"),
        "[cam_01].rotation",
    ),
    "fractional size": (_replace("size", "[64.5, 48.0]"), "[cam_01].size"),
    "negative size": (_replace("size", "[-64, 48]"), "[cam_01].size"),
    "fisheye": (_replace("fisheye", "true"), "[cam_01].fisheye"),
    "zero focal": (
        _replace("matrix", "[[0.0, 0.0, 31.5], [0.0, 50.0, 23.5], [0.0, 0.0, 1.0]]"),
        "[cam_01].matrix",
    ),
    "empty name": (_replace("name", '""'), "[cam_01].name"),
    "top-level scalar": ("version = 2\n" + GOOD_TABLE, "[version]"),
    "no cameras": ("[metadata]\nadjusted = false\n", "expected at least one camera"),
    "syntax error": (GOOD_TABLE + "[cam_02\n", "valid TOML"),
    "duplicate names": (GOOD_TABLE + GOOD_TABLE.replace("[cam_01]", "[cam_02]"), "camera names"),
}


@pytest.mark.parametrize("case", sorted(BAD_TOML))
def test_bad_toml_names_file_and_field(tmp_path, case):
    text, field = BAD_TOML[case]
    path = tmp_path / "bad.toml"
    path.write_text(text)
    with pytest.raises(InputError) as err:
        read_calibration(path)
    msg = str(err.value)
    assert str(path) in msg and field in msg, msg


def test_good_table_reads(tmp_path):
    """The template of the bad cases is itself valid (so each bad case tests one defect)."""
    path = tmp_path / "good.toml"
    path.write_text(GOOD_TABLE + "\n[metadata]\nerror = 0.0\n")
    rig = read_calibration(path)
    assert rig.names == ["cam_01"] and rig[0].size == (64, 48)


def test_missing_file_and_suffix(tmp_path):
    for name in ("nope.toml", "nope.yml"):
        with pytest.raises(InputError, match="no such file") as err:
            read_calibration(tmp_path / name)
        assert str(tmp_path / name) in str(err.value)
    (tmp_path / "calib.json").write_text("{}")
    with pytest.raises(InputError, match="suffix"):
        read_calibration(tmp_path / "calib.json")
    with pytest.raises(InputError, match="suffix"):
        write_calibration(tmp_path / "calib.json", Rig(()))


def test_binary_toml(tmp_path):
    path = tmp_path / "bin.toml"
    path.write_bytes(b"\xff\xfe\x00garbage")
    with pytest.raises(InputError) as err:
        read_calibration_toml(path)
    assert str(path) in str(err.value)


def test_write_refuses_empty_rig_and_reserved_name(tmp_path, make_rig):
    with pytest.raises(InputError, match="at least one camera"):
        write_calibration(tmp_path / "e.toml", Rig(()))
    rig = make_rig(np.random.default_rng(5), n_cams=1, names=["metadata"])
    with pytest.raises(InputError, match="reserved"):
        write_calibration(tmp_path / "m.toml", rig)
    assert list(tmp_path.iterdir()) == []


def _yaml_with(tmp_path, make_rig, edit):
    path = write_calibration_yaml(tmp_path / "c.yml", make_rig(np.random.default_rng(6), n_cams=2))
    path.write_text(edit(path.read_text()))
    return path


@pytest.mark.parametrize(
    "case,edit,field",
    [
        (
            "missing K",
            lambda s: s.replace("      K: !!opencv-matrix", "      Kx: !!opencv-matrix", 1),
            "cameras[0].K",
        ),
        (
            "missing R",
            lambda s: s.replace("      R: !!opencv-matrix", "      Rx: !!opencv-matrix", 1),
            "cameras[0].R",
        ),
        ("no cameras", lambda s: s.replace("cameras:", "cams:"), "cameras"),
        (
            "bad width",
            lambda s: s.replace("image_width: 64", "image_width: -64", 1),
            "cameras[0].image_width",
        ),
        ("garbage", lambda s: s.replace("---", "--- [ : {"), "FileStorage"),
    ],
)
def test_bad_yaml_names_file_and_field(tmp_path, make_rig, case, edit, field):
    path = _yaml_with(tmp_path, make_rig, edit)
    with pytest.raises(InputError) as err:
        read_calibration(path)
    assert str(path) in str(err.value) and field in str(err.value), str(err.value)


def test_yaml_rvec_accepted(tmp_path, make_rig, rigs_equal):
    rig = make_rig(np.random.default_rng(7), n_cams=1)
    path = write_calibration_yaml(tmp_path / "c.yaml", rig)
    rv = rig[0].rvec
    text = path.read_text()
    start = text.index("      R: !!opencv-matrix")
    end = text.index("      t: !!opencv-matrix")
    rvec = (
        f"      rvec: !!opencv-matrix\n         rows: 3\n         cols: 1\n         dt: d\n"
        f"         data: [ {float(rv[0])!r}, {float(rv[1])!r}, {float(rv[2])!r} ]\n"
    )
    path.write_text(text[:start] + rvec + text[end:])
    rigs_equal(rig, read_calibration(path), ROUNDTRIP_TOL)
    # a plain YAML sequence works as well as an !!opencv-matrix
    path.write_text(
        text[:start]
        + f"      rvec: [ {float(rv[0])!r}, {float(rv[1])!r}, {float(rv[2])!r} ]\n"
        + text[end:]
    )
    rigs_equal(rig, read_calibration(path), ROUNDTRIP_TOL)
