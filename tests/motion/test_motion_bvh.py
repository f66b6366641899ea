"""BVH reading, forward kinematics, mapping to 14 joints, export round trip, CMU real data."""

from __future__ import annotations

import os

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from toolkit.anthropometry.proportions import STATURE_RATIOS
from toolkit.errors import InputError
from toolkit.motion.bvh import (
    CMU_UNIT_M,
    bvh_to_skeleton14,
    euler_to_matrix,
    matrix_to_euler,
    motion_from_bvh,
    parse_bvh,
    read_bvh,
)
from toolkit.motion.bvh_write import write_bvh
from toolkit.motion.kinematics import bone_lengths14, sequence_bone_lengths
from toolkit.motion.library import MOTIONS, generate_motion
from toolkit.skeleton import SKELETON_14
from toolkit.skeleton.mappings import SKELETON14_BVH_TO_14, to_skeleton14

J = {n: i for i, n in enumerate(SKELETON_14.joint_names)}
#: Round trip tolerance of the exported file (written with 9 decimals), metres.
ROUND_TRIP_TOL_M = 1e-6
#: Bone lengths of a mocap skeleton are constant over time within this, metres.
CONSTANT_LENGTH_TOL_M = 1e-3
EXACT = 1e-9

ONE_JOINT = """HIERARCHY
ROOT root
{{
\tOFFSET 0 0 0
\tCHANNELS 6 Xposition Yposition Zposition {order}
\tJOINT tip
\t{{
\t\tOFFSET 0 0 1
\t\tCHANNELS 3 Xrotation Yrotation Zrotation
\t\tEnd Site
\t\t{{
\t\t\tOFFSET 0 2 0
\t\t}}
\t}}
}}
MOTION
Frames: 1
Frame Time: 0.04
1 2 3 {values} 0 0 0
"""


def test_euler_matches_scipy_intrinsic_rotations():
    rng = np.random.default_rng(0)
    a = rng.uniform(-180, 180, (50, 3))
    for order in ("ZYX", "XYZ", "YXZ", "ZXY"):
        R = euler_to_matrix(a, order)
        ref = Rotation.from_euler(order, a, degrees=True).as_matrix()   # uppercase = intrinsic
        np.testing.assert_allclose(R, ref, atol=EXACT)


def test_matrix_to_euler_inverts_zyx_including_gimbal_lock():
    rng = np.random.default_rng(1)
    a = rng.uniform(-170, 170, (200, 3))
    a[:, 1] = rng.uniform(-89, 89, 200)
    a[:5, 1] = [90, -90, 90, -90, 89.9999999]
    R = euler_to_matrix(a, "ZYX")
    back = matrix_to_euler(R)
    np.testing.assert_allclose(euler_to_matrix(back, "ZYX"), R, atol=EXACT)
    np.testing.assert_allclose(back[5:], a[5:], atol=1e-7)


@pytest.mark.parametrize("order, expected_tip", [
    # R = Rz(90) @ Rx(90): Rx takes (0,0,1) to (0,-1,0), Rz takes that to (1,0,0)
    ("Zrotation Xrotation Yrotation", [1, 0, 0]),
    # R = Rx(90) @ Rz(90): Rz leaves (0,0,1), Rx takes it to (0,-1,0)
    ("Xrotation Zrotation Yrotation", [0, -1, 0]),
])
def test_rotation_channels_apply_in_listed_order(order, expected_tip):
    m = parse_bvh(ONE_JOINT.format(order=order, values="90 90 0"), "one.bvh")
    pos = m.positions(end_sites=True)
    assert m.position_names(end_sites=True) == ("root", "tip", "tip_end")
    np.testing.assert_allclose(pos[0, 0], [1, 2, 3], atol=EXACT)
    np.testing.assert_allclose(pos[0, 1], np.array([1, 2, 3]) + expected_tip, atol=EXACT)
    assert m.fps == pytest.approx(25.0)


def test_sinusoidal_bvh_by_hand(cmu_dir):
    m = read_bvh(cmu_dir / "sinusoidal.bvh")
    assert m.joint_names == ("base", "child1", "child2", "child3") and m.n_frames == 120
    p = m.positions()
    # frame 0: base at (-3, 6, 5), child2 rotated -90 deg about x
    np.testing.assert_allclose(p[0], [[-3, 6, 5], [-3, 11, 5], [-8, 11, 5], [-8, 11, 2]], atol=EXACT)
    # child2's x angle goes -90 -> -45 -> -90 (0.75 s period): child3 stays 3 from child2
    np.testing.assert_allclose(np.linalg.norm(p[:, 3] - p[:, 2], axis=1), 3.0, atol=EXACT)
    k = int(np.argmax(m.motion[:, 9]))
    a = np.deg2rad(m.motion[k, 9])
    np.testing.assert_allclose(p[k, 3], [-8, 11 + 3 * np.cos(a), 5 + 3 * np.sin(a)], atol=EXACT)


@pytest.mark.parametrize("name", MOTIONS)
def test_export_import_round_trip(tmp_path, person, name):
    joints = generate_motion(name, person, 60, 25.0, rng=11)
    path = tmp_path / f"{name}.bvh"
    write_bvh(path, joints, fps=25.0)
    m = read_bvh(path)
    assert m.fps == pytest.approx(25.0) and m.n_frames == 60
    assert all(c[-3:] == ("Zrotation", "Yrotation", "Xrotation") for c in m.channels)
    back = bvh_to_skeleton14(m, SKELETON14_BVH_TO_14, units=0.01, up_axis="y", constant_lengths=False)
    assert np.abs(back - joints).max() < ROUND_TRIP_TOL_M
    assert not [f for f in os.listdir(tmp_path) if f.startswith(".")]     # no temporary file left


def test_export_rest_offsets_and_units(tmp_path, person):
    joints = generate_motion("walk", person, 10, 25.0, rng=1)
    write_bvh(tmp_path / "a.bvh", joints, 25.0, units=1.0, rest="first")
    m = read_bvh(tmp_path / "a.bvh")
    idx = {n: i for i, n in enumerate(m.joint_names)}
    assert m.parents[idx["neck"]] == -1
    # each bone's offset length is the bone length, in metres here
    for b, (_, c) in enumerate(SKELETON_14.bones):
        cn = SKELETON_14.joint_names[c]
        assert np.linalg.norm(m.offsets[idx[cn]]) == pytest.approx(bone_lengths14(person)[b], abs=1e-8)
    # rest pose: Y up, left side at +x, head above neck, feet below
    assert m.offsets[idx["head"], 1] > 0 and m.offsets[idx["l_shoulder"], 0] > 0
    assert m.offsets[idx["l_knee"], 1] < 0


def test_round_trip_overwrites_existing_file(tmp_path, person):
    path = tmp_path / "x.bvh"
    path.write_text("old")
    write_bvh(path, generate_motion("idle", person, 3, 25.0, rng=0), 25.0)
    assert read_bvh(path).n_frames == 3


@pytest.mark.parametrize("kwargs, where", [
    (dict(joints=np.zeros((5, 13, 3))), "joints"),
    (dict(joints=np.full((5, 14, 3), np.nan)), "joints"),
    (dict(fps=0.0), "fps"),
    (dict(rest="mean"), "rest"),
    (dict(skeleton=__import__("toolkit.skeleton", fromlist=["x"]).SKELETON_17), "skeleton"),
])
def test_write_bvh_bad_input(tmp_path, person, kwargs, where):
    args = dict(path=tmp_path / "x.bvh", joints=generate_motion("idle", person, 5, 25.0, rng=0), fps=25.0)
    args.update(kwargs)
    with pytest.raises(InputError) as e:
        write_bvh(**args)
    assert e.value.where == where
    assert not (tmp_path / "x.bvh").exists()


GOOD = ONE_JOINT.format(order="Zrotation Yrotation Xrotation", values="0 0 0")


@pytest.mark.parametrize("text, line, expected", [
    (GOOD.replace("HIERARCHY", "HIERARCHIE"), 1, "'HIERARCHY'"),
    (GOOD.replace("OFFSET 0 0 1", "OFFSET 0 zero 1"), 8, "offset value"),
    (GOOD.replace("Xrotation Yrotation Zrotation", "Xrotation Yrotation Wrotation"), 9, "channel name"),
    (GOOD.replace("\t}\n}\nMOTION", "\t}\nMOTION"), 15, "'JOINT', 'End Site' or '}'"),
    (GOOD.replace("1 2 3 0 0 0 0 0 0", "1 2 3 0 0 0 0 0"), 19, "9 channel values"),
    (GOOD.replace("1 2 3 0 0 0 0 0 0", "1 2 3 0 0 0 0 0 x"), 19, "a number"),
    (GOOD.replace("Frames: 1", "Frames: 2"), 19, "2 frames"),
    (GOOD.replace("Frame Time: 0.04", "Frame Time: 0"), 18, "positive frame time"),
    (GOOD.replace("JOINT tip", "JOINT root"), 6, "unique joint name"),
])
def test_malformed_bvh_names_file_and_line(text, line, expected):
    with pytest.raises(InputError) as e:
        parse_bvh(text, "bad.bvh")
    assert e.value.where == f"bad.bvh: line {line}"
    assert expected in e.value.expected


def test_read_bvh_missing_file(tmp_path):
    with pytest.raises(FileNotFoundError):
        read_bvh(tmp_path / "none.bvh")


def test_mapping_errors(person):
    m = parse_bvh(GOOD, "one.bvh")
    with pytest.raises(InputError, match="one.bvh: joints"):
        bvh_to_skeleton14(m)
    with pytest.raises(InputError, match="up_axis"):
        bvh_to_skeleton14(m, up_axis="x")


# ------------------------------------------------------------- CMU real data
def _cmu(cmu_dir):
    return read_bvh(cmu_dir / "01_01.bvh")


def test_cmu_file_structure(cmu_dir):
    m = _cmu(cmu_dir)
    assert m.n_frames == 2752
    assert m.fps == pytest.approx(120.0, rel=1e-4)
    assert len(m.position_names(end_sites=True)) == 38
    assert m.positions(end_sites=True).shape == (2752, 38, 3)
    assert m.channels[0] == ("Xposition", "Yposition", "Zposition", "Zrotation", "Yrotation", "Xrotation")


def test_cmu_mapped_skeleton_is_plausible(cmu_dir):
    m = _cmu(cmu_dir)
    raw = bvh_to_skeleton14(m, constant_lengths=False)
    j = bvh_to_skeleton14(m)
    z = j[..., 2]
    chain = ["head", "neck", "l_hip", "l_knee", "l_ankle"]
    for a, b in zip(chain, chain[1:]):
        assert np.mean(z[:, J[a]] > z[:, J[b]]) > 0.9, (a, b)
    for a, b in (("neck", "r_hip"), ("r_hip", "r_knee"), ("r_knee", "r_ankle")):
        assert np.mean(z[:, J[a]] > z[:, J[b]]) > 0.9, (a, b)
    # limbs map onto single BVH segments: constant without any correction
    L_raw = sequence_bone_lengths(raw)
    limbs = [i for i, n in enumerate(SKELETON_14.bone_names) if not n.startswith("neck-")]
    assert np.ptp(L_raw[:, limbs], axis=0).max() < CONSTANT_LENGTH_TOL_M
    assert np.ptp(sequence_bone_lengths(j), axis=0).max() < CONSTANT_LENGTH_TOL_M
    # stature from the leg length with the ANSUR ratio: 1.5 - 2.0 m
    L = np.median(sequence_bone_lengths(j), 0)
    leg = L[SKELETON_14.bone_names.index("l_hip-l_knee")] + L[SKELETON_14.bone_names.index("l_knee-l_ankle")]
    stature = leg / (STATURE_RATIOS["hip_height"] - STATURE_RATIOS["ankle_height"])
    assert 1.5 < stature < 2.0
    # the person's left is on their left: left = up x forward, forward from the toes
    pos = m.positions() * CMU_UNIT_M
    names = m.joint_names
    toe = pos[:, names.index("LeftToeBase")] - pos[:, names.index("LeftFoot")]
    fwd = np.stack([toe[:, 0], -toe[:, 2], toe[:, 1]], 1)      # the same y-up -> z-up rotation
    fwd[:, 2] = 0
    left = np.cross([0, 0, 1.0], fwd)
    assert np.mean(np.sum((j[:, J["l_hip"]] - j[:, J["r_hip"]]) * left, 1) > 0) > 0.9


def test_cmu_mapping_matches_keypoint_mapping(cmu_dir):
    m = _cmu(cmu_dir)
    pos = m.positions(end_sites=True)[:50]
    via_keypoints = to_skeleton14(pos, "cmu_bvh") * CMU_UNIT_M
    direct = bvh_to_skeleton14(m, constant_lengths=False)[:50]
    np.testing.assert_allclose(np.stack([via_keypoints[..., 0], -via_keypoints[..., 2], via_keypoints[..., 1]],
                                        -1), direct, atol=EXACT)


def test_motion_from_bvh_retargets_and_grounds(cmu_dir, person):
    j = motion_from_bvh(cmu_dir / "01_01.bvh", proportions=person, n_frames=100, fps=25.0, rng=3)
    assert j.shape == (100, 14, 3)
    np.testing.assert_allclose(sequence_bone_lengths(j), np.tile(bone_lengths14(person), (100, 1)), atol=EXACT)
    low = j[:, [J["l_ankle"], J["r_ankle"]], 2].min(1)
    assert low.min() >= person.ankle_height - EXACT
    assert np.percentile(low, 5, method="lower") == pytest.approx(person.ankle_height, abs=EXACT)
    pel = 0.5 * (j[:, J["l_hip"]] + j[:, J["r_hip"]])
    np.testing.assert_allclose(pel[:, :2].mean(0), 0, atol=EXACT)
    same = motion_from_bvh(cmu_dir / "01_01.bvh", proportions=person, n_frames=100, fps=25.0, rng=3)
    np.testing.assert_array_equal(j, same)
    full = motion_from_bvh(cmu_dir / "01_01.bvh", fps=30.0)
    assert len(full) == int((2752 - 1) / 120.0 * 30.0 + 1e-6) + 1
    with pytest.raises(InputError, match="n_frames"):
        motion_from_bvh(cmu_dir / "01_01.bvh", n_frames=10_000, fps=25.0)
