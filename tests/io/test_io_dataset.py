"""The dataset layout: writer -> reader round trip, validation errors, real footage."""

from __future__ import annotations

import os
import shutil

import cv2
import numpy as np
import pytest

from toolkit.cameras import Rig
from toolkit.errors import InputError
from toolkit.io.atomic import atomic_save_npz
from toolkit.io.calibration import read_calibration, write_calibration
from toolkit.io.dataset import Dataset, DatasetLayout
from toolkit.io.writer import DatasetWriter
from toolkit.io.video import write_video

#: mp4v round-trip error bound, as in test_io_video (measured 3.3-4.1 on small frames).
VIDEO_MAE_TOL = 5.0
#: Ground-truth 3D / 2D joints and calibrations are stored as float64: exact up to TOML repr.
EXACT_TOL = 1e-12
#: Depth is stored in whole millimetres (plus float32 rounding of the metres).
DEPTH_TOL_M = 0.0005 + 1e-6

N_FRAMES = 3
SIZE = (64, 48)
JOINT_NAMES = [
    "head",
    "neck",
    "l_shoulder",
    "l_elbow",
    "l_wrist",
    "r_shoulder",
    "r_elbow",
    "r_wrist",
    "l_hip",
    "l_knee",
    "l_ankle",
    "r_hip",
    "r_knee",
    "r_ankle",
]


def random_image(rng, size=SIZE) -> np.ndarray:
    """Random smooth RGB image (a 3x4 random colour grid, bicubically enlarged)."""
    coarse = rng.uniform(20, 235, (3, 4, 3)).astype(np.float32)
    return np.clip(cv2.resize(coarse, size, interpolation=cv2.INTER_CUBIC), 0, 255).astype(np.uint8)


def make_truth(rng, make_rig):
    gt_rig = make_rig(rng, n_cams=2, size=SIZE, names=["cam_a", "cam_b"])
    # measured cameras: the true ones with a small calibration error
    measured = Rig(tuple(c.replace(K=c.K + np.diag([0.5, 0.5, 0.0])) for c in gt_rig))
    novel = make_rig(rng, n_cams=1, size=(32, 24), names=["virtual"])
    w, h = SIZE
    truth = {
        "gt_rig": gt_rig,
        "rig": measured,
        "novel": novel,
        "rgb": {c: [random_image(rng) for _ in range(N_FRAMES)] for c in gt_rig.names},
        "mask": {c: [rng.random((h, w)) < 0.4 for _ in range(N_FRAMES)] for c in gt_rig.names},
        "parts": {
            c: [rng.integers(0, 11, (h, w), dtype=np.uint8) for _ in range(N_FRAMES)]
            for c in gt_rig.names
        },
        "depth": {
            c: [rng.uniform(1.0, 6.0, (h, w)) for _ in range(N_FRAMES)] for c in gt_rig.names
        },
        "joints3d": rng.normal([0, 0, 1], 0.4, (N_FRAMES, 14, 3)),
        "novel_rgb": [rng.integers(0, 256, (24, 32, 3), dtype=np.uint8) for _ in range(N_FRAMES)],
        "novel_mask": [rng.random((24, 32)) < 0.5 for _ in range(N_FRAMES)],
        "novel_parts": [rng.integers(0, 11, (24, 32), dtype=np.uint8) for _ in range(N_FRAMES)],
    }
    for c in gt_rig.names:
        truth["depth"][c][0][:5, :5] = np.nan  # no depth there
    truth["joints2d"] = {c.name: c.project(truth["joints3d"]) for c in gt_rig}
    return truth


def write_dataset(root, truth, *, n_frames=None) -> Dataset:
    n_frames = {} if n_frames is None else n_frames
    with DatasetWriter(root, fps=25) as w:
        w.write_calibration(truth["rig"])
        w.write_gt_calibration(truth["gt_rig"])
        w.write_novel_calibration(truth["novel"])
        for cam in truth["rig"].names:
            for i in range(n_frames.get(cam, N_FRAMES)):
                w.write_frame(cam, i, truth["rgb"][cam][i])
                w.write_mask(cam, i, truth["mask"][cam][i])
                w.write_parts(cam, i, truth["parts"][cam][i])
                w.write_depth(cam, i, truth["depth"][cam][i])
        for i in range(N_FRAMES):
            w.write_novel_image("virtual", i, truth["novel_rgb"][i])
            w.write_novel_mask("virtual", i, truth["novel_mask"][i])
            w.write_novel_parts("virtual", i, truth["novel_parts"][i])
        w.write_joints3d(truth["joints3d"], JOINT_NAMES)
        w.write_joints2d(truth["joints2d"])
        w.write_scene_toml("[scene]\nseed = 7\n")
        return w.close()


@pytest.fixture
def truth(make_rig):
    return make_truth(np.random.default_rng(11), make_rig)


@pytest.fixture
def dataset_root(tmp_path, truth):
    root = tmp_path / "ds"
    write_dataset(root, truth).close()
    return root


def mae(a, b) -> float:
    return float(np.abs(a.astype(np.int16) - b.astype(np.int16)).mean())


# ------------------------------------------------------------- round trip
def test_round_trip(dataset_root, truth, rigs_equal):
    with Dataset.open(dataset_root) as ds:
        assert ds.camera_names == ["cam_a", "cam_b"]
        assert ds.n_frames == N_FRAMES and ds.fps == 25.0 and ds.has_groundtruth
        rigs_equal(truth["rig"], ds.rig, EXACT_TOL)
        rigs_equal(truth["gt_rig"], ds.gt_rig, EXACT_TOL)
        rigs_equal(truth["novel"], ds.novel_rig, EXACT_TOL)
        for cam in ds.camera_names:
            frames = list(ds.frames(cam))
            assert len(frames) == N_FRAMES
            for i in (2, 0, 1):
                np.testing.assert_array_equal(ds.frame(cam, i), frames[i])
                assert mae(frames[i], truth["rgb"][cam][i]) < VIDEO_MAE_TOL
                mask = ds.gt_mask(cam, i)
                assert mask.dtype == bool
                np.testing.assert_array_equal(mask, truth["mask"][cam][i])
                np.testing.assert_array_equal(ds.gt_parts(cam, i), truth["parts"][cam][i])
                depth = ds.gt_depth(cam, i)
                assert depth.dtype == np.float32
                np.testing.assert_array_equal(np.isnan(depth), np.isnan(truth["depth"][cam][i]))
                ok = ~np.isnan(depth)
                assert np.abs(depth[ok] - truth["depth"][cam][i][ok]).max() <= DEPTH_TOL_M
        np.testing.assert_allclose(ds.gt_joints3d(), truth["joints3d"], rtol=0, atol=EXACT_TOL)
        assert ds.gt_joint_names == JOINT_NAMES
        j2 = ds.gt_joints2d()
        assert sorted(j2) == ["cam_a", "cam_b"]
        for cam, a in truth["joints2d"].items():
            np.testing.assert_allclose(j2[cam], a, rtol=0, atol=EXACT_TOL)
        for i in range(N_FRAMES):
            np.testing.assert_array_equal(ds.novel_image("virtual", i), truth["novel_rgb"][i])
            np.testing.assert_array_equal(ds.novel_mask("virtual", i), truth["novel_mask"][i])
            np.testing.assert_array_equal(ds.novel_parts("virtual", i), truth["novel_parts"][i])
        assert ds.scene_toml.read_text() == "[scene]\nseed = 7\n"
        assert ds.scene_rrd is None
    # nothing but the layout: no temporaries left behind
    names = {p.relative_to(dataset_root).as_posix() for p in dataset_root.rglob("*") if p.is_file()}
    assert not [n for n in names if "/." in n or n.startswith(".")]
    assert "videos/cam_a.mp4" in names and "groundtruth/masks/cam_b/000002.png" in names
    assert (
        "groundtruth/novel/virtual/000000.png" in names
        and "groundtruth/novel/parts/virtual/000002.png" in names
    )


def test_real_footage_layout_without_groundtruth(dataset_root):
    shutil.rmtree(dataset_root / "groundtruth")
    with Dataset.open(dataset_root) as ds:
        assert not ds.has_groundtruth
        for get in (
            lambda: ds.gt_rig,
            ds.gt_joints3d,
            ds.gt_joints2d,
            lambda: ds.gt_mask("cam_a", 0),
            lambda: ds.novel_rig,
        ):
            with pytest.raises(InputError, match="groundtruth"):
                get()


def test_accessor_errors(dataset_root):
    with Dataset.open(dataset_root) as ds:
        with pytest.raises(InputError, match="cam_z"):
            ds.frame("cam_z", 0)
        with pytest.raises(InputError, match="frame index"):
            ds.gt_mask("cam_a", N_FRAMES)
        with pytest.raises(InputError, match="virtual"):
            ds.novel_image("cam_a", 0)
    (dataset_root / "groundtruth/parts/cam_a/000001.png").unlink()
    with Dataset.open(dataset_root) as ds:
        with pytest.raises(InputError, match="no such file") as err:
            ds.gt_parts("cam_a", 1)
        assert "parts/cam_a/000001.png" in str(err.value)


# ------------------------------------------------------------- validation on open
def _expect(root, *fragments, **kwargs):
    with pytest.raises(InputError) as err:
        Dataset.open(root, **kwargs)
    msg = str(err.value)
    for f in fragments:
        assert str(f) in msg, msg
    return msg


def test_missing_calibration(dataset_root):
    (dataset_root / "calibration.toml").unlink()
    _expect(dataset_root, dataset_root / "calibration.toml", "no such file")
    _expect(dataset_root / "nothing", dataset_root / "nothing", "no such folder")


def test_camera_without_video(dataset_root):
    (dataset_root / "videos/cam_b.mp4").unlink()
    _expect(dataset_root, dataset_root / "videos/cam_b.mp4", "'cam_b'", "no such file")


def test_video_without_camera(dataset_root):
    shutil.copy(dataset_root / "videos/cam_a.mp4", dataset_root / "videos/cam_x.mp4")
    _expect(dataset_root, dataset_root / "videos/cam_x.mp4", "'cam_x'", "not in the calibration")


def test_videos_of_different_lengths(dataset_root, truth):
    write_video(dataset_root / "videos/cam_b.mp4", truth["rgb"]["cam_b"][:2], fps=25)
    _expect(dataset_root, "'cam_a' has 3 frames", "'cam_b' has 2")


def test_writer_refuses_different_lengths(tmp_path, truth):
    with pytest.raises(InputError, match="'cam_b' has 2"):
        write_dataset(tmp_path / "ds", truth, n_frames={"cam_b": 2})


def test_video_size_unlike_calibration(dataset_root, truth):
    rig = Rig(tuple(c.replace(size=(66, 48)) if c.name == "cam_a" else c for c in truth["rig"]))
    write_calibration(dataset_root / "calibration.toml", rig)
    _expect(dataset_root, dataset_root / "videos/cam_a.mp4", "66x48", "64x48")
    shutil.rmtree(dataset_root / "groundtruth")
    with Dataset.open(dataset_root, check_sizes=False) as ds:
        assert ds.video_sizes["cam_a"] == (64, 48)


def test_groundtruth_calibration_with_other_cameras(dataset_root, truth):
    rig = Rig((truth["gt_rig"][0],))
    write_calibration(dataset_root / "groundtruth/calibration.toml", rig)
    _expect(dataset_root, dataset_root / "groundtruth/calibration.toml", "cam_b")


@pytest.mark.parametrize(
    "arrays,fragment",
    [
        ({"joints": np.zeros((N_FRAMES, 14, 2)), "names": np.array(JOINT_NAMES)}, "(T, J, 3)"),
        ({"joints": np.zeros((N_FRAMES + 1, 14, 3)), "names": np.array(JOINT_NAMES)}, "3 frames"),
        ({"joints": np.zeros((N_FRAMES, 14, 3)), "names": np.array(JOINT_NAMES[:13])}, "names"),
        ({"joints": np.zeros((N_FRAMES, 14, 3))}, "'names'"),
        ({"names": np.array(JOINT_NAMES)}, "'joints'"),
    ],
)
def test_bad_joints3d(dataset_root, arrays, fragment):
    atomic_save_npz(dataset_root / "groundtruth/joints3d.npz", **arrays)
    _expect(dataset_root, dataset_root / "groundtruth/joints3d.npz", fragment)


def test_unreadable_npz(dataset_root):
    (dataset_root / "groundtruth/joints2d.npz").write_bytes(b"PK\x03\x04 truncated")
    _expect(dataset_root, dataset_root / "groundtruth/joints2d.npz", "readable .npz")


@pytest.mark.parametrize(
    "arrays,fragment",
    [
        ({"cam_a": np.zeros((N_FRAMES, 14, 3))}, "cam_a"),
        ({"cam_a": np.zeros((N_FRAMES, 13, 2))}, "(3, 14, 2)"),
        ({"cam_q": np.zeros((N_FRAMES, 14, 2))}, "'cam_q'"),
    ],
)
def test_bad_joints2d(dataset_root, arrays, fragment):
    atomic_save_npz(dataset_root / "groundtruth/joints2d.npz", **arrays)
    _expect(dataset_root, dataset_root / "groundtruth/joints2d.npz", fragment)


def test_bad_frame_folders(dataset_root):
    (dataset_root / "groundtruth/masks/cam_q").mkdir()
    _expect(dataset_root, dataset_root / "groundtruth/masks/cam_q", "'cam_q'")
    (dataset_root / "groundtruth/masks/cam_q").rmdir()
    shutil.copy(
        dataset_root / "groundtruth/masks/cam_a/000000.png",
        dataset_root / "groundtruth/masks/cam_a/000003.png",
    )
    _expect(dataset_root, "000003.png", "000002.png")


def test_keypoints_folder_holds_cameras_and_the_detectors_records(dataset_root):
    """keypoints/: one folder per camera, plus detection.json / sync.json of recipes/detect_keypoints.py."""
    kp = dataset_root / "keypoints"
    (kp / "cam_a").mkdir(parents=True)
    for name in ("detection.json", "sync.json"):
        (kp / name).write_text("{}")
    with Dataset.open(dataset_root) as ds:
        assert ds.has_keypoints and ds.keypoint_dir("cam_a") == kp / "cam_a"
    (kp / "notes.json").write_text("{}")
    _expect(dataset_root, kp / "notes.json", "'notes.json'")


def test_novel_folder_needs_calibration(dataset_root):
    (dataset_root / "groundtruth/novel/calibration.toml").unlink()
    _expect(dataset_root, dataset_root / "groundtruth/novel/calibration.toml", "no such file")


# ------------------------------------------------------------- writer errors
def test_writer_errors(tmp_path, truth):
    w = DatasetWriter(tmp_path / "ds", fps=25)
    img = truth["rgb"]["cam_a"][0]
    with pytest.raises(InputError, match=r"write_calibration\(\) called first"):
        w.write_frame("cam_a", 0, img)
    w.write_calibration(truth["rig"])
    with pytest.raises(InputError, match="cam_z"):
        w.write_frame("cam_z", 0, img)
    with pytest.raises(InputError, match="the next frame 0"):
        w.write_frame("cam_a", 1, img)
    with pytest.raises(InputError, match=r"shape \(48, 64, 3\)"):
        w.write_frame("cam_a", 0, img[:, :32])
    with pytest.raises(InputError, match=r"shape \(48, 64\)"):
        w.write_mask("cam_a", 0, np.zeros((64, 48), bool))
    with pytest.raises(InputError, match=r"\[0, 255\]"):
        w.write_parts("cam_a", 0, np.full((48, 64), 300, np.int32))
    with pytest.raises(InputError, match="integer part labels"):
        w.write_parts("cam_a", 0, np.zeros((48, 64), np.float32))
    with pytest.raises(InputError, match="negative"):
        w.write_depth("cam_a", 0, np.full((48, 64), -1.0))
    with pytest.raises(InputError, match="frame index"):
        w.write_mask("cam_a", -1, np.zeros((48, 64), bool))
    with pytest.raises(InputError, match=r"write_novel_calibration\(\) called first"):
        w.write_novel_image("virtual", 0, np.zeros((24, 32, 3), np.uint8))
    with pytest.raises(InputError, match="reserved|folders of the layout"):
        w.write_novel_calibration(Rig((truth["novel"][0].replace(name="masks"),)))
    with pytest.raises(InputError, match="names"):
        w.write_joints3d(np.zeros((3, 14, 3)), JOINT_NAMES[:3])
    with pytest.raises(InputError, match="key"):
        w.write_joints2d({"cam_q": np.zeros((3, 14, 2))})
    w.write_frame("cam_a", 0, img)
    with pytest.raises(InputError, match="cam_b"):  # a camera never written
        w.close()


def test_writer_abort_on_exception(tmp_path, truth):
    root = tmp_path / "ds"
    with pytest.raises(RuntimeError):
        with DatasetWriter(root, fps=25) as w:
            w.write_calibration(truth["rig"])
            w.write_frame("cam_a", 0, truth["rgb"]["cam_a"][0])
            raise RuntimeError("generator crashed")
    assert not (root / "videos").exists() or not any((root / "videos").iterdir())


# ------------------------------------------------------------- real footage
def test_pose2sim_demo_as_a_dataset(pose2sim_demo, tmp_path):
    """The Pose2Sim demo in this layout (links, not copies).

    Its calibration says 1088x1920 for every camera, but the videos of cam01
    and cam02 are 1080x1920 (those of cam03 and cam04 are 1088x1920).
    """
    root = tmp_path / "pose2sim"
    (root / "videos").mkdir(parents=True)
    os.symlink(pose2sim_demo / "S00_Calibration/Calib_qualisys.toml", root / "calibration.toml")
    trial = pose2sim_demo / "S00_P00_SingleParticipant/S00_P00_T01_BalancingTrial/videos"
    for cam in read_calibration(root / "calibration.toml").names:
        os.symlink(trial / f"{cam.replace('_', '')}.mp4", root / "videos" / f"{cam}.mp4")
    _expect(root, "1088x1920", "1080x1920", root / "videos/cam_01.mp4")
    with Dataset.open(root, check_sizes=False) as ds:
        assert ds.camera_names == ["cam_01", "cam_02", "cam_03", "cam_04"]
        assert ds.n_frames == 100 and ds.fps == 60.0 and not ds.has_groundtruth
        assert ds.video_sizes == {
            "cam_01": (1080, 1920),
            "cam_02": (1080, 1920),
            "cam_03": (1088, 1920),
            "cam_04": (1088, 1920),
        }
        assert ds.frame("cam_02", 10).shape == (1920, 1080, 3)
        assert DatasetLayout(root).video("cam_03") == ds.video_path("cam_03")
