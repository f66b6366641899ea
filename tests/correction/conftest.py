"""A tiny stage-1 run for the correction tests: three far cameras, a green screen, chroma keying.

The dataset is made with the exact ray caster (no Open3D) as in ``tests/recipes``: flat part
colours over a green screen, so chroma keying gives clean silhouettes in milliseconds, and the
ground truth (3D joints, their projections) is exact.  ``pose_from_silhouettes.py`` runs once
per test session on it with a small walking database (about 10 s).
"""

from __future__ import annotations

import importlib
import shutil
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from toolkit.anthropometry.proportions import BodyProportions
from toolkit.cameras import Camera, Rig
from toolkit.io import DatasetWriter
from toolkit.motion import generate_motion
from toolkit.silhouettes import BuildConfig, build_database
from toolkit.skeleton import SKELETON_14
from toolkit.body.model import BodyModel
from toolkit.synthetic.render import Raycaster

REPO = Path(__file__).resolve().parents[2]
N_FRAMES = 3
#: Flat colour per part id (0 unused); no green, so chroma keying removes the screen only.
COLOURS = np.array([[0, 0, 0], [225, 185, 150], [190, 40, 40], [215, 125, 95], [215, 125, 95], [170, 50, 50],
                    [205, 105, 85], [40, 40, 130], [70, 45, 25], [45, 45, 150], [80, 55, 35]], np.uint8)
CAMERA_AZIMUTHS_DEG = (-60.0, 30.0, 120.0)


def load_recipe(name: str):
    return importlib.import_module(f"recipes.{name}")


def _camera(name, centre, az_deg):
    a = np.radians(az_deg)
    eye = [centre[0] + 30 * np.cos(a), centre[1] + 30 * np.sin(a), 8.0]
    return Camera.look_at(name, eye, [centre[0], centre[1], 1.0], size=(480, 270), focal_px=3000.0)


def _green_screen(labels: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    h, w = labels.shape
    img = np.empty((h, w, 3), np.uint8)
    img[..., 0] = rng.integers(10, 40, (h, w))
    img[..., 1] = rng.integers(150, 190, (h, w))
    img[..., 2] = rng.integers(10, 40, (h, w))
    body = labels > 0
    img[body] = COLOURS[labels[body]]
    return img


@pytest.fixture(scope="session")
def tiny_run(tmp_path_factory):
    """A dataset, a database and a finished stage-1 run of it (never modified: copy before writing)."""
    base = tmp_path_factory.mktemp("correction")
    root = base / "walk"
    rng = np.random.default_rng(7)
    props = BodyProportions.sample(1.75, rng)
    body = BodyModel.sample(props, rng, detail=0.4)
    joints = generate_motion("walk", props, N_FRAMES, 25.0, rng)
    c = joints[0, 1, :2]
    rig = Rig(tuple(_camera(f"cam_{i}", c, az) for i, az in enumerate(CAMERA_AZIMUTHS_DEG)))
    caster = Raycaster()
    with DatasetWriter(root, 25.0) as w:
        w.write_calibration(rig)
        w.write_gt_calibration(rig)
        for t in range(N_FRAMES):
            mesh = body.mesh(joints[t])
            for cam in rig:
                labels, subject, _ = caster.cast(cam, [mesh])
                w.write_frame(cam.name, t, _green_screen(labels, rng))
                w.write_mask(cam.name, t, subject > 0)
        w.write_joints3d(joints, SKELETON_14.joint_names)
        w.write_joints2d({cam.name: cam.project(joints) for cam in rig})
    db = build_database(BuildConfig(motions=("walk",), sequences_per_motion=2, frames_per_sequence=40,
                                    frame_stride=4, views_per_pose=12), 5)
    db_path = db.save(base / "db.npz")
    out = base / "run"
    rc = load_recipe("pose_from_silhouettes").main([str(root), "--out", str(out), "--db", str(db_path),
                                                    "--foreground", "chroma", "--no-recording", "--quiet"])
    assert rc == 0
    return SimpleNamespace(dataset=root, db=db_path, run=out, joints=joints, rig=rig)


@pytest.fixture
def run_copy(tiny_run, tmp_path):
    """A writable copy of the run and of the database."""
    run = tmp_path / "run"
    shutil.copytree(tiny_run.run, run)
    db = tmp_path / "db.npz"
    shutil.copyfile(tiny_run.db, db)
    return SimpleNamespace(run=run, db=db, dataset=tiny_run.dataset, joints=tiny_run.joints, rig=tiny_run.rig)
