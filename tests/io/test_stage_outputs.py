"""Typed stage outputs (toolkit.io.stage_outputs): round trips, the files' keys, bad folders named."""

from __future__ import annotations

import numpy as np
import pytest

from toolkit.errors import InputError
from toolkit.io import atomic_save_npz
from toolkit.io.stage_outputs import (
    STAGE1_VIEW_KEYS,
    FreeViewpointPoses,
    Stage1Output,
    read_free_viewpoint_poses,
    read_stage1_output,
    write_free_viewpoint_poses,
    write_stage1,
)
from toolkit.skeleton import SKELETON_14

T, C, K = 5, 3, 2
CAMS = ("cam_a", "cam_b", "cam_c")


def _output(rng) -> Stage1Output:
    joints = rng.normal(size=(T, 14, 3))
    joints[2] = np.nan  # a frame without estimate
    offsets = rng.normal(size=(T, C, 2)) * 3
    offsets[1, 2] = np.nan  # a view that took no part
    return Stage1Output(joints, CAMS, offsets, {c: rng.uniform(0, 640, (T, 14, 2)) for c in CAMS},
                        state=rng.integers(0, 4, T).astype(np.uint8), cost=rng.uniform(0, 0.1, T),
                        view_state=rng.integers(0, 3, (T, C)).astype(np.uint8), bbox=rng.uniform(0, 600, (T, C, 4)),
                        candidates=rng.uniform(0, 640, (T, C, K, 14, 2)), candidate_errors=rng.uniform(0, 1, (T, C, K)),
                        candidate_index=rng.integers(-1, 100, (T, C, K)), edited=rng.uniform(size=(T, C)) < 0.3)


def _same(a, b):
    assert type(a) is type(b)
    np.testing.assert_array_equal(np.asarray(a), np.asarray(b))


def test_stage1_round_trip_and_keys(tmp_path):
    out = _output(np.random.default_rng(0))
    files = write_stage1(tmp_path, out)
    assert sorted(f.name for f in files) == ["offsets.npz", "poses2d.npz", "poses3d.npz"]
    # the keys the runs wrote before the type existed, in the same order
    assert np.load(tmp_path / "poses2d.npz").files == list(CAMS) + list(STAGE1_VIEW_KEYS) + ["cameras"]
    assert np.load(tmp_path / "poses3d.npz").files == ["joints", "names", "state", "cost"]
    assert np.load(tmp_path / "offsets.npz").files == ["offsets", "cameras", "state"]
    back = read_stage1_output(tmp_path)
    assert back.cameras == CAMS and back.joint_names == tuple(SKELETON_14.joint_names) and back.n_frames == T
    for name in ("joints", "offsets", "state", "cost") + STAGE1_VIEW_KEYS:
        _same(getattr(back, name), getattr(out, name))
        assert getattr(back, name).dtype == np.asarray(getattr(out, name)).dtype, name
    assert sorted(back.poses2d) == sorted(CAMS)
    for c in CAMS:
        _same(back.poses2d[c], out.poses2d[c])
    lean = read_stage1_output(tmp_path, poses2d=False)
    assert lean.poses2d == {} and lean.candidates is None and lean.cameras == CAMS


def test_stage1_minimal_folder_and_missing_offsets(tmp_path):
    """A folder with joints alone (as a hand-made one) reads with offsets 0, given the cameras."""
    joints = np.random.default_rng(1).normal(size=(T, 14, 3))
    atomic_save_npz(tmp_path / "poses3d.npz", joints=joints)
    with pytest.raises(InputError, match="camera names"):
        read_stage1_output(tmp_path)
    out = read_stage1_output(tmp_path, cameras=CAMS)
    _same(out.joints, joints)
    assert out.offsets.shape == (T, C, 2) and not out.offsets.any()
    assert out.state is None and out.poses2d == {} and out.cameras == CAMS


@pytest.mark.parametrize("file, key, value, message", [
    ("poses3d.npz", "joints", None, "an array 'joints'"),
    ("poses3d.npz", "joints", np.zeros((T, 13, 3)), r"shape \(T, 14, 3\)"),
    ("offsets.npz", "offsets", None, "an array 'offsets'"),
    ("offsets.npz", "offsets", np.zeros((T, C + 1, 2)), r"shape \(T=5, C=3, 2\)"),
    ("offsets.npz", "offsets", np.zeros((T - 1, C, 2)), r"shape \(T=5, C=3, 2\)"),
    ("poses2d.npz", "cam_b", np.zeros((T, 14, 3)), r"shape \(T=5, 14, 2\)"),
    ("poses2d.npz", "candidates", np.zeros((T, C, K, 14)), "shape"),
    ("poses2d.npz", "cameras", np.array(["cam_a", "cam_x", "cam_c"]), "cam_x"),
    ("poses3d.npz", "state", np.zeros(T + 1, np.uint8), r"shape \(T=5\)"),
])
def test_stage1_bad_files_name_file_and_key(tmp_path, file, key, value, message):
    write_stage1(tmp_path, _output(np.random.default_rng(2)))
    with np.load(tmp_path / file) as z:
        arrays = {k: z[k] for k in z.files}
    if value is None:
        del arrays[key]
    else:
        arrays[key] = value
    atomic_save_npz(tmp_path / file, **arrays)
    with pytest.raises(InputError, match=message) as e:
        read_stage1_output(tmp_path)
    assert file in str(e.value)


def test_stage1_missing_poses3d_and_other_cameras(tmp_path):
    with pytest.raises(InputError, match="poses3d.npz"):
        read_stage1_output(tmp_path, cameras=CAMS)
    write_stage1(tmp_path, _output(np.random.default_rng(3)))
    with pytest.raises(InputError, match="cam_b"):
        read_stage1_output(tmp_path, cameras=("cam_a", "cam_c", "cam_b"))


def test_stage1_output_checks_its_fields():
    out = _output(np.random.default_rng(4))
    with pytest.raises(InputError, match="Stage1Output.offsets"):
        Stage1Output(out.joints, CAMS[:2], out.offsets)
    with pytest.raises(InputError, match="Stage1Output.poses2d"):
        Stage1Output(out.joints, CAMS, out.offsets, {"cam_z": out.poses2d["cam_a"]})
    with pytest.raises(InputError, match="Stage1Output.cameras"):
        Stage1Output(out.joints, ("cam_a", "bbox", "cam_c"), out.offsets)
    with pytest.raises(InputError, match="Stage1Output.cost"):
        Stage1Output(out.joints, CAMS, out.offsets, cost=np.zeros(T - 1))


def test_free_viewpoint_poses_round_trip_and_bad_file(tmp_path):
    rng = np.random.default_rng(5)
    poses = FreeViewpointPoses(rng.normal(size=(T, 14, 3)), rng.normal(size=(T, 14, 3)),
                               np.array(["ok", "not processed", "ok", "no stage-1 pose", "ok"]))
    write_free_viewpoint_poses(tmp_path, poses)
    assert np.load(tmp_path / "poses3d.npz").files == ["joints", "names", "joints_stage1", "status"]
    back = read_free_viewpoint_poses(tmp_path)
    for name in ("joints", "joints_stage1", "status"):
        _same(getattr(back, name), getattr(poses, name))
    assert back.joint_names == tuple(SKELETON_14.joint_names)
    with pytest.raises(InputError, match="FreeViewpointPoses.status"):
        FreeViewpointPoses(poses.joints, poses.joints_stage1, poses.status[:3])
    atomic_save_npz(tmp_path / "poses3d.npz", joints=poses.joints, status=poses.status)
    with pytest.raises(InputError, match="joints_stage1"):
        read_free_viewpoint_poses(tmp_path)
