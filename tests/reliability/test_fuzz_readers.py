"""Readers fed damaged files: every outcome a reading or an InputError, never another exception or a hang.

Property-based (``hypothesis``): each valid file is damaged by a drawn
mutation (bytes overwritten, cut short, garbage inserted, a span repeated or
deleted, a digit turned into another character) and read again; hypothesis
searches the mutations and shrinks a failing one to the smallest.  The
examples per reader are bounded (:data:`N_MUTATIONS`, derandomized: the same
ones on every run) so the whole file runs in seconds.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from toolkit.cameras import Camera, Rig
from toolkit.errors import InputError
from toolkit.io.calibration import read_calibration, write_calibration
from toolkit.io.depth_readers import depth_intrinsics_text, read_depth, read_depth_intrinsics
from toolkit.io.atomic import atomic_write_png
from toolkit.io.keypoint_files import read_camera_detections
from toolkit.io.text import load_json, load_toml

#: Damaged copies read per reader (derandomized: the same ones on every run).
N_MUTATIONS = 60

#: One damage: (kind, where as a share of the length, a second share, garbage bytes, a repeat count).
MUTATIONS = st.tuples(st.integers(0, 5), st.floats(0, 1), st.floats(0, 1), st.binary(min_size=1, max_size=32),
                      st.integers(1, 4))


def mutate(data: bytes, m) -> bytes:
    """``data`` with the damage ``m`` (one draw of :data:`MUTATIONS`)."""
    kind, where, other, garbage, times = m
    b = bytearray(data)
    if not b:
        return bytes(garbage)
    i = min(int(where * len(b)), len(b) - 1)
    span = 1 + int(other * 63)
    if kind == 0:                                   # bytes overwritten
        b[i:i + len(garbage)] = garbage[:len(b) - i]
    elif kind == 1:                                 # cut short
        b = b[:i]
    elif kind == 2:                                 # garbage inserted
        b[i:i] = garbage
    elif kind == 3:                                 # a span repeated
        b[i:i] = b[i:i + span] * times
    elif kind == 4:                                 # a span deleted
        del b[i:i + span]
    else:                                           # a digit changed into another character
        digits = [k for k, c in enumerate(b) if chr(c).isdigit()]
        if digits:
            b[digits[min(int(other * len(digits)), len(digits) - 1)]] = b"-e.x9 [\""[times % 8]
    return bytes(b)


def fuzz(path, read) -> int:
    """Read damaged copies of ``path`` (hypothesis draws the damage); returns how many were refused."""
    original = path.read_bytes()
    refused = [0]

    @settings(max_examples=N_MUTATIONS, deadline=None, derandomize=True, database=None,
              suppress_health_check=[HealthCheck.too_slow])
    @given(MUTATIONS)
    def one(m):
        path.write_bytes(mutate(original, m))
        try:
            read(path)
        except InputError as e:
            assert str(path) in str(e) or path.name in str(e), str(e)
            refused[0] += 1

    try:
        one()
    finally:
        path.write_bytes(original)
    read(path)
    return refused[0]


def rig() -> Rig:
    return Rig(tuple(Camera.look_at(f"cam_{i}", [4 * np.cos(a), 4 * np.sin(a), 1.5], [0, 0, 1], size=(640, 480),
                                    fov_x_deg=60, dist=[-0.1, 0.01, 0.0, 0.0, 0.0])
                     for i, a in enumerate(np.radians([0, 120, 240]))))


@pytest.mark.parametrize("suffix", [".toml", ".yml"])
def test_calibration(tmp_path, suffix):
    path = write_calibration(tmp_path / f"calib{suffix}", rig())
    assert fuzz(path, read_calibration) > N_MUTATIONS // 3


def test_keypoint_json(tmp_path):
    kp = np.tile([320.0, 240.0, 0.9], 25)
    f = tmp_path / "cam01" / "cam01.0000.json"
    f.parent.mkdir()
    f.write_text(json.dumps({"version": 1.3, "people": [{"person_id": [-1], "pose_keypoints_2d": kp.tolist()},
                                                        {"person_id": [-1], "pose_keypoints_2d": kp.tolist()}]}))
    assert fuzz(f, lambda p: read_camera_detections(p.parent)) > 0


def test_depth_frames(tmp_path):
    d = (np.arange(48 * 64).reshape(48, 64) % 3000 + 500).astype(np.uint16)
    png = tmp_path / "000000.png"
    atomic_write_png(png, d)
    fuzz(png, read_depth)
    npy = tmp_path / "f.npy"
    np.save(npy, d.astype(np.float32) / 1000)
    fuzz(npy, read_depth)
    raw = tmp_path / "raw"
    d.astype("<u2").tofile(raw)
    fuzz(raw, lambda p: read_depth(p, size=(64, 48)))


def test_depth_intrinsics(tmp_path):
    f = tmp_path / "intrinsics.toml"
    f.write_text(depth_intrinsics_text(rig()[0]))
    assert fuzz(f, read_depth_intrinsics) > 0


def test_text_readers(tmp_path):
    t = tmp_path / "c.toml"
    t.write_text('seed = 5\n[tracker]\nfps = 15.0\nnames = ["a", "b"]\n[tracker.orus]\nbin_size_m = 0.06\n')
    fuzz(t, load_toml)
    j = tmp_path / "c.json"
    j.write_text(json.dumps({"a": [1, 2, {"b": [3.5, None, "x"]}], "c": True}))
    fuzz(j, load_json)


def test_trajectory_files(tmp_path):
    from toolkit.io.c3d import read_c3d as read_c3d_points
    from toolkit.io.trajectories import read_c3d, read_csv, read_trc, skeleton14_trajectories, write_trajectories
    from toolkit.skeleton import SKELETON_14

    rng = np.random.default_rng(9)
    joints = rng.normal(0, 0.5, (4, 14, 3)) + [0, 0, 1]
    traj = skeleton14_trajectories(joints, SKELETON_14.joint_names, np.arange(4), 30.0, {"source": "fuzz"})
    files = {p.suffix: p for p in write_trajectories(tmp_path / "poses", traj)}
    fuzz(files[".trc"], read_trc)
    fuzz(files[".csv"], read_csv)
    fuzz(files[".c3d"], read_c3d)
    fuzz(files[".c3d"], read_c3d_points)


def test_qualisys_calibration(tmp_path):
    from pathlib import Path

    demo = Path(__file__).resolve().parents[2].parent / "shared" / "realdata" / "pose2sim_demo"
    files = sorted(demo.glob("**/Calib*.qca.txt"))
    if not files:
        pytest.skip(f"real data not found under {demo}")
    f = tmp_path / "Calib.qca.txt"
    f.write_bytes(files[0].read_bytes())
    assert fuzz(f, read_calibration) > 0


def test_bvh(tmp_path):
    from toolkit.motion import write_bvh
    from toolkit.motion.bvh import read_bvh

    rng = np.random.default_rng(15)
    joints = rng.normal(0, 0.02, (3, 14, 3)) + _standing()
    path = tmp_path / "m.bvh"
    write_bvh(path, joints, 30.0)
    assert fuzz(path, read_bvh) > 0


def _standing() -> np.ndarray:
    """A standing 14-joint pose (metres, z up)."""
    from toolkit.anthropometry.proportions import BodyProportions

    return BodyProportions.from_height(1.75).rest_pose()


def test_dataset_layout(tmp_path, make_rig):
    """A dataset with one file damaged, removed or added: ``Dataset.open`` and every reader of it give a
    reading or an ``InputError``, never another exception."""
    import shutil

    from toolkit.io import Dataset
    from tests.io.test_io_dataset import make_truth, write_dataset

    clean = tmp_path / "clean"
    write_dataset(clean, make_truth(np.random.default_rng(11), make_rig)).close()
    files = sorted(p.relative_to(clean) for p in clean.rglob("*") if p.is_file())
    work = tmp_path / "work"

    def read_all(root):
        with Dataset.open(root) as ds:
            for cam in ds.camera_names:
                for i in range(ds.n_frames):
                    ds.frame(cam, i)
                    ds.gt_mask(cam, i)
                    ds.gt_parts(cam, i)
                    ds.gt_depth(cam, i)
            ds.gt_joints3d()
            ds.gt_joints2d()
            assert ds.gt_rig is not None

    @settings(max_examples=N_MUTATIONS, deadline=None, derandomize=True, database=None,
              suppress_health_check=[HealthCheck.too_slow])
    @given(st.sampled_from(files), st.sampled_from(["damaged", "removed", "stray"]), MUTATIONS)
    def one(rel, how, m):
        shutil.rmtree(work, ignore_errors=True)
        shutil.copytree(clean, work)
        target = work / rel
        if how == "damaged":
            target.write_bytes(mutate(target.read_bytes(), m))
        elif how == "removed":
            target.unlink()
        else:
            (target.parent / f"stray{m[4]}{target.suffix}").write_bytes(m[3])
        try:
            read_all(work)
        except InputError:
            pass

    read_all(clean)
    one()
