"""End to end: recipes/pose_from_silhouettes.py (and build_silhouette_db.py) on a tiny synthetic dataset.

The dataset is made here, without the Open3D renderer: a person walking in
front of a green screen (part colours from the exact ray-cast labels), seen by
two far broadcast-like cameras, so that chroma keying gives clean silhouettes
in a few milliseconds per frame.
"""

from __future__ import annotations

import importlib
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from toolkit.anthropometry.proportions import BodyProportions
from toolkit.cameras import Camera, Rig
from toolkit.io import DatasetWriter, write_video
from toolkit.motion import generate_motion
from toolkit.silhouettes import BuildConfig, SilhouetteDatabase, build_database
from toolkit.silhouettes.descriptor import STATE_NO_FRAME, STATE_OK
from toolkit.silhouettes.pipeline import FRAME_OK, estimate_dataset
from toolkit.skeleton import SKELETON_14
from toolkit.body.model import BodyModel
from toolkit.synthetic.render import Raycaster

REPO = Path(__file__).resolve().parents[2]
N_FRAMES = 4
#: Mean 3D joint error over the clip with chroma-keyed silhouettes and a 480-entry walking database
#: (measured 40-60 mm): bound with a 1.5x margin.
MPJPE_BOUND_M = 0.09
#: Part colours (RGB): none of them green, so the chroma key removes only the screen.
PART_RGB = np.array([[0, 0, 0], [230, 190, 160], [200, 30, 30], [220, 120, 90], [220, 120, 90], [180, 40, 40],
                     [200, 100, 80], [30, 30, 120], [60, 40, 20], [40, 40, 140], [70, 50, 30]], np.uint8)


def load_recipe(name: str):
    return importlib.import_module(f"recipes.{name}")


def green_screen(mask_labels: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    h, w = mask_labels.shape
    img = np.empty((h, w, 3), np.uint8)
    img[..., 0] = rng.integers(10, 40, (h, w))
    img[..., 1] = rng.integers(150, 190, (h, w))
    img[..., 2] = rng.integers(10, 40, (h, w))
    body = mask_labels > 0
    img[body] = PART_RGB[mask_labels[body]]
    return img


@pytest.fixture(scope="module")
def tiny_dataset(tmp_path_factory):
    root = tmp_path_factory.mktemp("data") / "walk"
    rng = np.random.default_rng(5)
    props = BodyProportions.sample(1.75, rng)
    model = BodyModel.sample(props, rng, detail=0.4)
    joints = generate_motion("walk", props, N_FRAMES, 25.0, rng)
    c = joints[0, 1, :2]
    cams = []
    for i, az in enumerate((-60.0, 30.0)):
        a = np.radians(az)
        eye = [c[0] + 30 * np.cos(a), c[1] + 30 * np.sin(a), 8.0]
        cams.append(Camera.look_at(f"cam_{i}", eye, [c[0], c[1], 1.0], size=(480, 270), focal_px=3000.0))
    rig = Rig(tuple(cams))
    caster = Raycaster()
    with DatasetWriter(root, 25.0) as w:
        w.write_calibration(rig)
        w.write_gt_calibration(rig)
        for t in range(N_FRAMES):
            mesh = model.mesh(joints[t])
            for cam in rig:
                labels, subject, _ = caster.cast(cam, [mesh])
                w.write_frame(cam.name, t, green_screen(labels, rng))
                w.write_mask(cam.name, t, subject > 0)
        w.write_joints3d(joints, SKELETON_14.joint_names)
        w.write_joints2d({cam.name: cam.project(joints) for cam in rig})
    return SimpleNamespace(root=root, joints=joints, rig=rig)


@pytest.fixture(scope="module")
def small_db_path(tmp_path_factory):
    db = build_database(BuildConfig(motions=("walk",), sequences_per_motion=2, frames_per_sequence=40, frame_stride=4,
                                    views_per_pose=12), 5)
    return db.save(tmp_path_factory.mktemp("db") / "walk.npz")


def test_recipe_end_to_end(tiny_dataset, small_db_path, tmp_path, capsys):
    recipe = load_recipe("pose_from_silhouettes")
    out = tmp_path / "out"
    rc = recipe.main([str(tiny_dataset.root), "--out", str(out), "--db", str(small_db_path),
                      "--foreground", "chroma", "--quiet"])
    assert rc == 0
    printed = capsys.readouterr().out
    assert str(out / "poses3d.npz") in printed and "recording.rrd" in printed
    for name in ("poses2d.npz", "poses3d.npz", "offsets.npz", "recording.rrd", "edits_template.toml",
                 "calibration.toml"):
        assert (out / name).is_file() and (out / name).stat().st_size > 0
    # no field model in this dataset: the cameras used are the measured ones, written for later stages
    from toolkit.io import read_calibration
    used = read_calibration(out / "calibration.toml")
    assert used.names == tiny_dataset.rig.names
    assert all(np.allclose(a.cam_from_world, b.cam_from_world) for a, b in zip(used, tiny_dataset.rig))
    with np.load(out / "poses3d.npz") as z:
        joints, names, state = z["joints"], list(z["names"]), z["state"]
    assert joints.shape == (N_FRAMES, 14, 3) and names == list(SKELETON_14.joint_names)
    assert np.all(state == FRAME_OK)
    mpjpe = np.linalg.norm(joints - tiny_dataset.joints, axis=-1).mean()
    assert mpjpe < MPJPE_BOUND_M
    with np.load(out / "poses2d.npz") as z:
        assert z["cam_0"].shape == (N_FRAMES, 14, 2) and z["cam_1"].shape == (N_FRAMES, 14, 2)
        assert np.all(z["view_state"] == STATE_OK)
        assert z["candidates"].shape == (N_FRAMES, 2, 3, 14, 2)
        assert list(z["cameras"]) == ["cam_0", "cam_1"]
    with np.load(out / "offsets.npz") as z:
        assert z["offsets"].shape == (N_FRAMES, 2, 2) and np.isfinite(z["offsets"]).all()


def test_recipe_applies_edits_and_grows_the_database(tiny_dataset, small_db_path, tmp_path):
    recipe = load_recipe("pose_from_silhouettes")
    db_path = tmp_path / "db.npz"
    db_path.write_bytes(small_db_path.read_bytes())
    n0 = len(SilhouetteDatabase.load(db_path))
    xy = tiny_dataset.rig[1].project(tiny_dataset.joints[2])[SKELETON_14.index("r_wrist")]
    edits = tmp_path / "edits.toml"
    edits.write_text(f'[[edit]]\nframe = 2\ncamera = "cam_1"\njoints = {{ r_wrist = [{xy[0]:.2f}, {xy[1]:.2f}] }}\n')
    out = tmp_path / "out"
    rc = recipe.main([str(tiny_dataset.root), "--out", str(out), "--db", str(db_path), "--foreground", "chroma",
                      "--edits", str(edits), "--max-frames", "3", "--no-recording", "--quiet"])
    assert rc == 0
    db = SilhouetteDatabase.load(db_path)
    assert len(db) == n0 + 1 and db.motion[-1] == "user" and db.frame[-1] == 2
    with np.load(out / "poses2d.npz") as z:
        np.testing.assert_allclose(z["cam_1"][2, SKELETON_14.index("r_wrist")], xy, atol=0.01)
        assert z["edited"][2].tolist() == [False, True]
        assert z["cam_0"].shape == (3, 14, 2)  # --max-frames 3 of 4
    with np.load(out / "poses3d.npz") as z:
        assert z["state"].shape == (3,)
    assert not (out / "recording.rrd").exists()


def test_recipe_errors_are_clear(tiny_dataset, tmp_path, capsys):
    recipe = load_recipe("pose_from_silhouettes")
    empty = SilhouetteDatabase.empty().save(tmp_path / "empty.npz")
    rc = recipe.main([str(tiny_dataset.root), "--out", str(tmp_path / "o"), "--db", str(empty), "--quiet"])
    assert rc == 2 and "empty database" in capsys.readouterr().err
    bad = tmp_path / "edits.toml"
    bad.write_text('[[edit]]\nframe = 0\ncamera = "nope"\njoints = { head = [1, 2] }\n')
    rc = recipe.main([str(tiny_dataset.root), "--out", str(tmp_path / "o"), "--db", str(empty), "--edits", str(bad)])
    assert rc == 2 and "camera" in capsys.readouterr().err
    rc = recipe.main([str(tmp_path / "missing"), "--out", str(tmp_path / "o")])
    assert rc == 2 and "missing" in capsys.readouterr().err


def test_a_shorter_video_gives_no_frame_states(tiny_dataset, small_db_path, tmp_path):
    """A video that ends early: its view is left out from then on, the others go on."""
    from toolkit.foreground import ForegroundConfig
    from toolkit.io import Dataset

    ds = Dataset.open(tiny_dataset.root)
    short = tmp_path / "cam_1.mp4"
    write_video(short, [ds.frame("cam_1", i) for i in range(2)], 25.0)
    third = Camera.look_at("cam_2", [30.0, 5.0, 7.0], [0.0, 0.0, 1.0], size=(480, 270), focal_px=2800.0)
    paths = {"cam_0": ds.video_path("cam_0"), "cam_1": short, "cam_2": ds.video_path("cam_0")}
    fake = SimpleNamespace(camera_names=["cam_0", "cam_1", "cam_2"], n_frames=N_FRAMES,
                           rig=Rig((ds.rig[0], ds.rig[1], third)), video_path=lambda c: paths[c])
    db = SilhouetteDatabase.load(small_db_path)
    out = list(estimate_dataset(fake, db, foreground=ForegroundConfig(method="chroma"), log_images=False))
    assert len(out) == N_FRAMES
    for t, (est, masks) in enumerate(out):
        if t >= 2:
            assert masks[1] is None and est.view_states[1] == STATE_NO_FRAME
            assert np.isnan(est.poses2d[1]).all()
        else:
            assert est.view_states[1] == STATE_OK
        assert "foreground" in est.timings and "query" in est.timings
    ds.close()


def test_build_silhouette_db_recipe(tmp_path, capsys):
    recipe = load_recipe("build_silhouette_db")
    out = tmp_path / "db.npz"
    rc = recipe.main(["--out", str(out), "--motions", "kick", "--sequences", "1", "--frames", "10", "--stride", "5",
                      "--views", "3", "--workers", "1", "--quiet"])
    assert rc == 0
    db = SilhouetteDatabase.load(out)
    assert len(db) == 2 * 3 * 2 and set(db.motion.tolist()) == {"kick"}
    assert "entries/s" in capsys.readouterr().out
    assert recipe.main(["--out", str(out), "--motions", "", "--workers", "1"]) == 2


def test_help_runs():
    for name in ("pose_from_silhouettes", "build_silhouette_db"):
        with pytest.raises(SystemExit) as info:
            load_recipe(name).main(["--help"])
        assert info.value.code == 0


def test_recipe_with_the_flow_term(tiny_dataset, tmp_path):
    """--flow-weight: dense optical flow per camera, matched against a database built with flows."""
    db = build_database(BuildConfig(motions=("walk",), sequences_per_motion=1, frames_per_sequence=20, frame_stride=2,
                                    views_per_pose=8, with_flow=True), 5)
    path = db.save(tmp_path / "flow.npz")
    out = tmp_path / "out"
    rc = load_recipe("pose_from_silhouettes").main(
        [str(tiny_dataset.root), "--out", str(out), "--db", str(path), "--foreground", "chroma", "--flow-weight", "1",
         "--max-frames", "3", "--no-recording", "--quiet"])
    assert rc == 0
    with np.load(out / "poses3d.npz") as z:
        assert np.all(z["state"] == FRAME_OK) and np.isfinite(z["joints"]).all()


def test_recipe_config_file_and_run_identity(tiny_dataset, small_db_path, tmp_path, capsys):
    """--config: the estimator's options from TOML tables (flags win); another run's folder is refused."""
    recipe = load_recipe("pose_from_silhouettes")
    cfg = tmp_path / "stage1.toml"
    cfg.write_text('foreground = "chroma"\nmax_frames = 2\n[stage1.query]\nk = 2\n')
    out = tmp_path / "out"
    args = [str(tiny_dataset.root), "--out", str(out), "--db", str(small_db_path), "--config", str(cfg),
            "--no-recording", "--quiet"]
    assert recipe.main(args) == 0
    with np.load(out / "poses2d.npz") as z:
        assert z["candidates"].shape == (2, 2, 2, 14, 2)  # max_frames and k from the file
    assert recipe.main(args + ["--k", "3"]) == 2  # other options: OUT holds another run's results
    assert "stage1.query.k" in capsys.readouterr().err
    assert recipe.main(args + ["--k", "3", "--replace-stale"]) == 0
    assert (tmp_path / "out.stale-1" / "poses3d.npz").is_file()
    with np.load(out / "poses2d.npz") as z:
        assert z["candidates"].shape[2] == 3
    cfg.write_text('[stage1.query]\nkk = 2\n')
    assert recipe.main(args) == 2 and "kk" in capsys.readouterr().err
