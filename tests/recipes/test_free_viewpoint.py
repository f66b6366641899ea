"""End to end: recipes/free_viewpoint.py on a small green-screen dataset with a novel camera.

The dataset is built here with the exact ray caster (no Open3D): flat part
colours in front of a green screen, two far cameras (chroma keying gives clean
silhouettes), one novel camera between them whose ground truth is the same
flat-coloured body over black.
"""

from __future__ import annotations

import importlib
import json
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from toolkit.anthropometry.proportions import BodyProportions
from toolkit.cameras import Camera, Rig
from toolkit.io import DatasetWriter
from toolkit.io.frames import read_png
from toolkit.motion import generate_motion
from toolkit.silhouettes import BuildConfig, build_database
from toolkit.skeleton import SKELETON_14
from toolkit.body.model import BodyModel
from toolkit.synthetic.render import Raycaster

RERUN = Path(sys.executable).with_name("rerun")

REPO = Path(__file__).resolve().parents[2]
N_FRAMES = 2
#: Flat colour per part id (0 unused); no green, so chroma keying removes the screen only.
COLOURS = np.array([[0, 0, 0], [225, 185, 150], [190, 40, 40], [215, 125, 95], [215, 125, 95], [170, 50, 50],
                    [205, 105, 85], [40, 40, 130], [70, 45, 25], [45, 45, 150], [80, 55, 35]], np.uint8)
#: Articulated billboards on the novel view, PSNR in the subject's box over black (measured 15.9 dB with
#: the 7 cm pose error of stage 1 on 30 m cameras, i.e. several pixels of misplacement).
NOVEL_PSNR_DB = 14.0
#: Articulated over standard billboards on the same views (measured +2.5 dB; the benchmark checks +2 dB).
ARTICULATED_MARGIN_DB = 1.0
#: Share of the true mask the articulated novel view covers with opacity > 0.5: measured 0.86-0.88 with
#: the 5 cm stage-1 pose error here (several pixels of misplacement on 30 m cameras; 0.98 with true joints,
#: tests/rendering/test_any_direction.py); the standard billboards cover 0.55.
MIN_COVERAGE = 0.8
#: Mean 3D joint error with a 240-entry walking database and chroma keying (measured ~5-8 cm): 2x margin.
MPJPE_BOUND_M = 0.15


def _load_recipe():
    return importlib.import_module("recipes.free_viewpoint")


def _far_camera(name, centre, az_deg):
    a = np.radians(az_deg)
    eye = [centre[0] + 30 * np.cos(a), centre[1] + 30 * np.sin(a), 8.0]
    return Camera.look_at(name, eye, [centre[0], centre[1], 1.0], size=(480, 270), focal_px=3000.0)


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    root = tmp_path_factory.mktemp("fvv") / "walk"
    rng = np.random.default_rng(11)
    props = BodyProportions.sample(1.75, rng)
    body = BodyModel.sample(props, rng, detail=0.4)
    joints = generate_motion("walk", props, N_FRAMES, 25.0, rng)
    c = joints[0, 1, :2]
    rig = Rig((_far_camera("cam_0", c, -50.0), _far_camera("cam_1", c, 40.0)))
    novel = Rig((_far_camera("novel_0", c, -5.0),))
    caster = Raycaster()
    with DatasetWriter(root, 25.0) as w:
        w.write_calibration(rig)
        w.write_gt_calibration(rig)
        w.write_novel_calibration(novel)
        for t in range(N_FRAMES):
            mesh = body.mesh(joints[t])
            for cam in rig:
                labels, subject, _ = caster.cast(cam, [mesh])
                img = np.empty(labels.shape + (3,), np.uint8)
                img[:] = rng.integers(10, 40, labels.shape + (3,))
                img[..., 1] = rng.integers(150, 190, labels.shape)
                img[labels > 0] = COLOURS[labels[labels > 0]]
                w.write_frame(cam.name, t, img)
                w.write_mask(cam.name, t, subject > 0)
                w.write_parts(cam.name, t, labels)
            for cam in novel:
                labels, subject, _ = caster.cast(cam, [mesh])
                w.write_novel_image(cam.name, t, COLOURS[labels])
                w.write_novel_mask(cam.name, t, subject > 0)
                w.write_novel_parts(cam.name, t, labels)
        w.write_joints3d(joints, SKELETON_14.joint_names)
        w.write_joints2d({cam.name: cam.project(joints) for cam in rig})
    db = build_database(BuildConfig(motions=("walk",), sequences_per_motion=2, frames_per_sequence=40,
                                    frame_stride=4, views_per_pose=12), 5)
    db_path = db.save(tmp_path_factory.mktemp("db") / "walk.npz")
    return root, db_path


@pytest.mark.timeout(600)
def test_free_viewpoint_end_to_end_and_resume(dataset, tmp_path, capsys):
    root, db_path = dataset
    recipe = _load_recipe()
    out = tmp_path / "out"
    # the truth is the body over black: judged over the "plates" background (black without a scene.toml)
    conf = tmp_path / "plates.toml"
    conf.write_text('background = "plates"\n')
    rc = recipe.main([str(root), "--out", str(out), "--workers", "1",
                      "--db", str(db_path), "--foreground", "chroma", "--quiet",
                      "--config", str(conf)])
    assert rc == 0
    z = np.load(out / "poses3d.npz")
    assert z["joints"].shape == (N_FRAMES, 14, 3) and list(z["names"]) == list(SKELETON_14.joint_names)
    for t in range(N_FRAMES):
        name = f"{t:06d}.png"
        for cam in ("cam_0", "cam_1"):
            assert read_png(out / "parts" / cam / name).max() > 0
        assert read_png(out / "novel" / "novel_0" / name).shape == (270, 480, 3)
        for method in ("standard", "visual_hull"):
            assert (out / "baselines" / method / "novel_0" / name).exists()
        # the articulated subject's opacity and the background alone, for coverage checks
        alpha = read_png(out / "novel_alpha" / "novel_0" / name)
        assert alpha.shape == (270, 480) and alpha.dtype == np.uint8 and alpha.max() == 255 and alpha.min() == 0
        gt_mask = read_png(root / "groundtruth" / "novel" / "masks" / "novel_0" / name) > 0
        assert np.mean(alpha[gt_mask] > 127) >= MIN_COVERAGE
        assert not read_png(out / "baselines" / "plate" / "novel_0" / name).any()  # black: no scene.toml
    for p in ("orbit", "sweep", "birds_eye"):
        assert (out / "paths" / f"{p}.mp4").stat().st_size > 0
    assert (out / "recording.rrd").stat().st_size > 0
    m = json.loads((out / "metrics.json").read_text())
    assert m["finished"] == N_FRAMES
    assert m["methods"]["articulated"]["n"] == N_FRAMES
    assert m["methods"]["articulated"]["psnr"] > NOVEL_PSNR_DB
    assert m["methods"]["articulated"]["psnr"] > m["methods"]["standard"]["psnr"] + ARTICULATED_MARGIN_DB
    for method in ("articulated", "standard", "visual_hull"):  # the keys the zoo benchmark reads
        s = m["methods"][method]
        assert np.isfinite(s["psnr_subject"]) and 0.0 <= s["coverage_min"] <= s["coverage"] <= 1.0
    assert m["methods"]["articulated"]["coverage_min"] >= MIN_COVERAGE
    frame0 = json.loads((out / "frames" / "000000.json").read_text())
    assert {"psnr", "ssim", "psnr_subject", "coverage", "psnr_frame"} <= set(frame0["scores"]["articulated"]["novel_0"])
    assert not (out / "scene").exists()
    assert m["pose"]["mpjpe_m"] < MPJPE_BOUND_M
    assert sum(m["optimize"].values()) == 14 * N_FRAMES  # how stage 3 ended for every joint of every frame
    # every second of a frame has a key: its parts add up to its total (issue 20); stage 1 is outside it
    from toolkit.pipeline.free_viewpoint import WITHIN_TOTAL

    spf = m["seconds_per_frame"]
    assert spf["stage1"] > spf["foreground"] > 0 and spf["views"] > 0 and spf["paths"] > 0 and spf["other"] >= 0
    assert sum(spf[k] for k in WITHIN_TOTAL) + spf["other"] == pytest.approx(spf["total"])
    assert "stage 3 joints:" in capsys.readouterr().out
    capsys.readouterr()

    # an interrupted run: one frame lost its result; the rerun redoes that frame only, and its recording
    # goes beside the first one (same recording id) instead of overwriting it
    novel0 = out / "novel" / "novel_0" / "000000.png"
    before = novel0.stat().st_mtime_ns
    first_rec = (out / "recording.rrd").stat()
    (out / "frames" / "000001.json").unlink()
    rc = recipe.main([str(root), "--out", str(out), "--workers", "1",
                      "--db", str(db_path), "--foreground", "chroma", "--quiet",
                      "--config", str(conf)])
    assert rc == 0
    printed = capsys.readouterr().out
    assert "resuming: 1 of 2" in printed and "(1 this run" in printed
    assert "cameras: reusing" in printed and (out / "calibration.toml").is_file()
    assert novel0.stat().st_mtime_ns == before
    assert (out / "frames" / "000001.json").exists()
    second = out / "recording.resume-1.rrd"
    assert second.stat().st_size > 0 and "recording*.rrd" in printed
    after = (out / "recording.rrd").stat()
    assert (after.st_size, after.st_mtime_ns) == (first_rec.st_size, first_rec.st_mtime_ns)
    assert RERUN.exists(), f"the rerun CLI comes with rerun-sdk: {RERUN}"
    ids = []  # both parts are one recording for the viewer: same application and recording id
    for f in (out / "recording.rrd", second):
        p = subprocess.run([str(RERUN), "rrd", "print", str(f)], capture_output=True, text=True)
        assert p.returncode == 0, p.stderr
        ids.append(re.search(r'"free_viewpoint",\s*"([0-9a-f-]+)"', p.stdout).group(1))
    assert ids[0] == ids[1]
    # nothing left to do: no new recording part
    rc = recipe.main([str(root), "--out", str(out), "--workers", "1",
                      "--db", str(db_path), "--foreground", "chroma", "--quiet",
                      "--config", str(conf)])
    assert rc == 0 and "already finished" in capsys.readouterr().out
    assert not (out / "recording.resume-2.rrd").exists()

    # other options (or another dataset): the finished frames are not resumed ...
    rc = recipe.main([str(root), "--out", str(out), "--workers", "1",
                      "--db", str(db_path), "--foreground", "chroma", "--quiet",
                      "--config", str(conf), "--no-recording", "--no-baselines", "--no-optimize", "--max-frames", "1"])
    assert rc == 2
    err = capsys.readouterr().err
    assert str(out) in err and "optimize" in err and "--replace-stale" in err
    assert (out / "frames" / "000001.json").exists()
    # ... unless asked: then they are moved aside, not deleted
    rc = recipe.main([str(root), "--out", str(out), "--workers", "1",
                      "--db", str(db_path), "--foreground", "chroma", "--quiet",
                      "--config", str(conf), "--no-recording", "--no-baselines", "--no-optimize", "--max-frames", "1", "--replace-stale"])
    assert rc == 0
    assert (tmp_path / (out.name + ".stale-1") / "frames" / "000001.json").exists()
    assert (out / "frames" / "000000.json").exists() and not (out / "frames" / "000001.json").exists()


def test_bad_dataset_is_a_clear_error(tmp_path, capsys):
    recipe = _load_recipe()
    rc = recipe.main([str(tmp_path / "missing"), "--out", str(tmp_path / "o"), "--workers", "1", "--quiet"])
    assert rc == 2
    assert "error:" in capsys.readouterr().err
    with pytest.raises(SystemExit) as e:
        recipe.main([str(tmp_path / "missing"), "--out", str(tmp_path / "o"), "--workers", "1", "--jpeg-quality", "0"])
    assert e.value.code == 2 and "--jpeg-quality" in capsys.readouterr().err


def test_each_frame_is_decoded_once(dataset, tmp_path, monkeypatch):
    """Stage 1 and the frame's stages read a camera's frame through one decoder (issue 16 item 4)."""
    from collections import Counter

    from toolkit.io import video

    root, db_path = dataset
    decoded = Counter()
    original = video.VideoReader._decode_next

    def counting(self):
        decoded[(self.path.name, self._next)] += 1
        return original(self)

    monkeypatch.setattr(video.VideoReader, "_decode_next", counting)
    # the scene model (background "scene") reads its sample of frames once more, before the run, and so does
    # the search for several people (people "all": up to 8 frames per camera): both left out here
    conf = tmp_path / "plates.toml"
    conf.write_text('background = "plates"\n')
    rc = _load_recipe().main([str(root), "--out", str(tmp_path / "o"), "--workers", "1",
                              "--db", str(db_path), "--foreground",
                              "chroma", "--quiet", "--no-recording", "--no-optimize", "--no-baselines",
                              "--config", str(conf), "--people", "main"])
    assert rc == 0
    assert len(decoded) == 2 * N_FRAMES  # every (camera, frame) was read
    assert set(decoded.values()) == {1}, f"frames decoded more than once: {decoded}"
