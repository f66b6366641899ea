"""The depth-tracking recipe on a small synthetic dataset and on the real Kinect frames."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest
from recipes import depth_tracking
from tests.depth.conftest import REPO_ROOT
from toolkit.anthropometry.proportions import BodyProportions
from toolkit.pointcloud.cloud import ViewFrame
from toolkit.depth.evaluate import plausibility
from toolkit.pointcloud.mask import user_mask
from toolkit.io.depth_readers import default_depth_camera, list_depth_frames, read_depth
from toolkit.motion import generate_motion
from toolkit.body.model import BodyModel
from toolkit.synthetic.depth_sensor import DepthCameraSpec, render_depth_camera

#: MPJPE the recipe must reach on the small synthetic dataset (8 standing frames, 320 x 240, noise).
RECIPE_MPJPE_MM = 45.0
#: Real frames whose skeleton must be plausible (head above the shoulders, arms inside the silhouette).
MIN_PLAUSIBLE_REAL = 10


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    root = tmp_path_factory.mktemp("depth_ds")
    props = BodyProportions.sample(1.72, 11)
    model = BodyModel.sample(props, 11, detail=0.5)
    J = generate_motion("idle", props, 8, 30.0, rng=11)
    render_depth_camera(root, DepthCameraSpec(resolution=(320, 240), environment="floor"), model, J, rng=11)
    return root


def test_recipe_tracks_a_dataset(dataset, tmp_path, capsys):
    out = tmp_path / "track"
    assert depth_tracking.main([str(dataset), "--out", str(out), "--quiet", "--images", str(out / "img")]) == 0
    printed = capsys.readouterr().out
    assert "skeleton (world coordinates)" in printed and "recording.rrd" in printed
    z = np.load(out / "skeleton.npz", allow_pickle=False)
    assert z["joints"].shape == (8, 13, 3) and list(z["names"])[0] == "head"
    assert z["state"].dtype == np.int8 and z["state"][-1] == 2 and str(z["coordinates"]) == "world"
    assert z["observed"].shape == (8, 13) and len(z["frames"]) == 8
    m = json.loads((out / "metrics.json").read_text())
    assert m["mpjpe_mm"] < RECIPE_MPJPE_MM and m["frames"] == 8
    assert (out / "recording.rrd").stat().st_size > 10_000
    assert len(list((out / "img").glob("*.png"))) == 8


def test_recipe_on_a_folder_of_raw_frames(tmp_path):
    """Raw uint16 frames with the default Kinect camera; unreadable input is a clean error."""
    frames = tmp_path / "frames"
    frames.mkdir()
    for i in range(3):
        np.zeros((48, 64), "<u2").tofile(frames / f"depth-{i}")
    out = tmp_path / "out"
    assert depth_tracking.main([str(frames), "--out", str(out), "--size", "64", "48", "--quiet",
                                "--no-recording"]) == 0
    z = np.load(out / "skeleton.npz")
    assert list(z["state"]) == [0, 0, 0] and np.isnan(z["joints"]).all() and str(z["coordinates"]) == "camera"
    assert depth_tracking.main([str(tmp_path / "missing"), "--out", str(out), "--quiet"]) == 2
    assert depth_tracking.main([str(frames), "--out", str(out), "--quiet"]) == 2     # 640 x 480 expected


def test_recipe_help():
    r = subprocess.run([sys.executable, str(REPO_ROOT / "recipes" / "depth_tracking.py"), "--help"],
                       capture_output=True, text=True, timeout=60)
    assert r.returncode == 0 and "--independent" in r.stdout and "skeleton.npz" in r.stdout


def test_real_kinect_frames_are_plausible(kinect_dir, tmp_path):
    out = tmp_path / "kinect"
    assert depth_tracking.main([str(kinect_dir), "--out", str(out), "--independent", "--quiet",
                                "--no-recording"]) == 0
    z = np.load(out / "skeleton.npz")
    cam = default_depth_camera()
    frame = ViewFrame.from_camera(cam, pose_known=False)
    files = list_depth_frames(kinect_dir)
    ok = 0
    for i, f in enumerate(files):
        assert z["state"][i] != 0, f.name
        d = read_depth(f)
        p = plausibility(z["joints"][i], frame, user_mask(d, cam).mask)
        ok += p.ok()
    assert ok >= MIN_PLAUSIBLE_REAL


def test_recipe_run_identity_and_config_file(tmp_path, capsys):
    """One sequence is one identified run: the same run again replaces it, other options are refused
    (or moved aside); options come from a TOML file too, unknown keys rejected."""
    frames = tmp_path / "frames"
    frames.mkdir()
    for i in range(2):
        np.zeros((48, 64), "<u2").tofile(frames / f"depth-{i}")
    out = tmp_path / "out"
    common = [str(frames), "--out", str(out), "--size", "64", "48", "--quiet", "--no-recording"]
    assert depth_tracking.main(common) == 0
    capsys.readouterr()
    assert depth_tracking.main(common + ["--frames", "1"]) == 2            # fewer frames than the folder holds
    assert "2 frames" in capsys.readouterr().err
    assert len(np.load(out / "skeleton.npz")["state"]) == 2                # kept, not rewritten for 1 frame
    assert depth_tracking.main(common + ["--frames", "5"]) == 0            # how many frames: not the identity
    capsys.readouterr()
    assert depth_tracking.main(common + ["--seed", "5"]) == 2
    assert "seed" in capsys.readouterr().err
    cfg = tmp_path / "run.toml"
    cfg.write_text("seed = 5\n[tracker]\nfps = 15.0\n[tracker.orus]\nbin_size_m = 0.06\n")
    assert depth_tracking.main(common + ["--config", str(cfg), "--replace-stale"]) == 0
    assert (tmp_path / "out.stale-1" / "skeleton.npz").is_file()
    ident = json.loads((out / "run.json").read_text())["config"]
    assert ident["seed"] == 5 and ident["tracker"]["fps"] == 15.0 and ident["tracker"]["orus"]["bin_size_m"] == 0.06
    assert depth_tracking.main(common + ["--config", str(cfg), "--fps", "20"]) == 2   # the flag wins: another run
    cfg.write_text("[tracker]\nfsp = 15.0\n")
    assert depth_tracking.main(common + ["--config", str(cfg)]) == 2
    err = capsys.readouterr().err
    assert f"{cfg}: tracker.fsp" in err and "fps" in err
