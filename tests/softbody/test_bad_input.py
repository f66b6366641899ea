"""Bad input to recipes/fit_soft_body.py (issue 18): a clear error (exit 2, ``error: ...``, no traceback)
or an explicit per-frame state, never a crash or a silently wrong fit."""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest

from recipes import fit_soft_body as recipe

SPEC = """
name = "softbody_bad"
seed = 19
frames = 3
fps = 30

[subject]
height_m = 1.70
motion = "kick"

[cameras]
count = 1
layout = "studio"
resolution = [64, 48]

[depth_camera]
resolution = [320, 240]
noise = true
environment = "studio"
distance_m = 3.0
"""


def _run(argv):
    return recipe.main([str(a) for a in argv] + ["--no-recording", "--quiet"])


def _fails(argv, capsys, *words):
    """The recipe exits with 2 and one ``error:`` line naming ``words``; no traceback."""
    assert _run(argv) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and "Traceback" not in err, err
    for w in words:
        assert w in err, (w, err)


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    from recipes import make_scene

    root = tmp_path_factory.mktemp("sb")
    (root / "spec.toml").write_text(SPEC)
    assert make_scene.main([str(root / "spec.toml"), "--out", str(root / "d"), "--no-recording", "--quiet"]) == 0
    d = root / "d"
    np.savez(root / "truth.npz", joints=np.load(d / "groundtruth" / "joints3d.npz")["joints"])
    return d, root / "truth.npz"


def _depth(path):
    import cv2

    return cv2.imread(str(path), cv2.IMREAD_UNCHANGED)


def _variant(dataset, dst, edit):
    """A copy of the dataset whose depth frames are ``edit(t, depth, background)`` (uint16 mm)."""
    import cv2

    shutil.copytree(dataset, dst)
    bg = _depth(dst / "depth_camera" / "background.png")
    for t, p in enumerate(sorted((dst / "depth_camera" / "depth").glob("*.png"))):
        cv2.imwrite(str(p), edit(t, _depth(p), bg).astype(np.uint16))
    return dst


def _mpjpe_mm(out, truth):
    j = np.load(out / "joints.npz")["joints"]
    return 1000 * np.linalg.norm(j - np.load(truth)["joints"][:len(j)], axis=-1).mean(axis=-1)


def test_missing_dataset_wrong_source_and_options(tmp_path, capsys, dataset):
    d, _ = dataset
    _fails([tmp_path / "absent", "--out", tmp_path / "o1"], capsys, "absent", "no such folder")
    (tmp_path / "empty").mkdir()
    _fails([tmp_path / "empty", "--out", tmp_path / "o2"], capsys, "empty", "depth frame")
    _fails([d, "--out", tmp_path / "o3", "--source", "stereo"], capsys, "trinocular head")
    _fails([d, "--out", tmp_path / "o4", "--frames", "0"], capsys, "--frames", ">= 1")
    # before: an initial frame past the frames used was silently replaced by the last one
    _fails([d, "--out", tmp_path / "o5", "--frames", "2", "--init-frame", "2"], capsys, "--init-frame", "[0, 2)")


def test_joints_file_of_wrong_shape_units_or_values(tmp_path, capsys, dataset):
    d, truth = dataset
    j = np.load(truth)["joints"]
    bad = {"j10": np.zeros((10, 3)), "jT": j.transpose(0, 2, 1), "jnan": np.where(np.arange(14)[:, None] == 5,
                                                                                np.nan, j[0])}
    for name, arr in bad.items():
        np.savez(tmp_path / f"{name}.npz", joints=arr)
    np.savez(tmp_path / "nokey.npz", other=j)
    (tmp_path / "garbage.npz").write_bytes(b"garbage")
    np.savez(tmp_path / "mm.npz", joints=1000 * j)
    one = ["--frames", "1", "--no-global-fit"]
    _fails([d, "--out", tmp_path / "o1", "--init-joints", tmp_path / "j10.npz", *one], capsys,
           "j10.npz: joints", "(T, 14, 3)", "(10, 3)")
    _fails([d, "--out", tmp_path / "o2", "--init-joints", tmp_path / "jT.npz", *one], capsys, "(3, 3, 14)")
    _fails([d, "--out", tmp_path / "o3", "--init-joints", truth, "--frames", "3", "--init-frame", "3"], capsys,
           "--init-frame")
    np.savez(tmp_path / "short.npz", joints=j[:1])
    _fails([d, "--out", tmp_path / "o4", "--init-joints", tmp_path / "short.npz", "--init-frame", "1"], capsys,
           "short.npz: joints", "frame 1")
    _fails([d, "--out", tmp_path / "o5", "--init-joints", tmp_path / "nokey.npz", *one], capsys, "nokey.npz", "'joints'")
    _fails([d, "--out", tmp_path / "o6", "--init-joints", tmp_path / "garbage.npz", *one], capsys, "garbage.npz")
    _fails([d, "--out", tmp_path / "o7", "--init-joints", tmp_path / "absent.npz", *one], capsys, "absent.npz")
    # before: a NaN joint was refused without naming the file
    _fails([d, "--out", tmp_path / "o8", "--init-joints", tmp_path / "jnan.npz", *one], capsys,
           "jnan.npz: joints", "finite", "in 1")
    # before: millimetres gave exit 0, a model clipped to 2.1 m on 1000-times bones and an 'empty' frame
    _fails([d, "--out", tmp_path / "o9", "--init-joints", tmp_path / "mm.npz", *one], capsys,
           "joints", "metres", "1.7e+03 m")


def test_person_leaves_no_depth_and_tiny_cloud_are_frame_states(tmp_path, dataset):
    """Frame 1: the empty scene but six pixels of the person (a tiny cloud, the person left);
    frame 2: no depth at all.  The global fit runs over the good frame; every frame has joints."""
    d, truth = dataset

    def edit(t, depth, bg):
        if t == 1:
            out = bg.copy().ravel()
            px = np.flatnonzero((depth != bg).ravel())[:6]
            out[px] = depth.ravel()[px]
            return out.reshape(bg.shape)
        return np.zeros_like(depth) if t == 2 else depth

    v = _variant(d, tmp_path / "leave", edit)
    assert _run([v, "--out", tmp_path / "o", "--init-joints", truth]) == 0
    z = np.load(tmp_path / "o" / "joints.npz")
    assert list(z["state"]) == ["ok", "empty", "empty"]
    assert np.isfinite(z["joints"]).all()
    m = json.loads((tmp_path / "o" / "metrics.json").read_text())
    assert m["states"] == {"empty": 2, "ok": 1}
    assert _mpjpe_mm(tmp_path / "o", truth)[0] < 60


def test_floor_in_view_without_an_empty_scene(tmp_path, dataset):
    """No background.png: the floor is in the depth frames and only the user mask removes it."""
    d, truth = dataset
    v = tmp_path / "nobg"
    shutil.copytree(d, v)
    (v / "depth_camera" / "background.png").unlink()
    assert _run([v, "--out", tmp_path / "o", "--init-joints", truth, "--frames", "2", "--no-global-fit"]) == 0
    z = np.load(tmp_path / "o" / "joints.npz")
    assert list(z["state"]) == ["ok", "ok"]
    assert np.all(_mpjpe_mm(tmp_path / "o", truth) < 60)


@pytest.mark.xfail(strict=True, reason="a second person touching the subject joins its cloud (one foreground blob) "
                                       "and pulls the fit sideways frame after frame while every state stays 'ok' "
                                       "(datasets_synthetic/depth_touching.toml, 3 frames: MPJPE 110, 203, 294 mm "
                                       "from the true joints); toolkit/pointcloud and softbody/track.py are being "
                                       "edited by others")
def test_second_person_beside_the_subject(tmp_path, dataset):
    """A second copy of the person 0.45 m to the side (its depth pixels shifted), touching the first."""
    d, truth = dataset

    def edit(t, depth, bg):
        person = (depth != bg) & (depth > 0)
        shift = 45  # pixels: ~0.45 m at 3 m with this camera
        other = np.zeros_like(person)
        other[:, shift:] = person[:, :-shift]
        moved = np.zeros_like(depth)
        moved[:, shift:] = depth[:, :-shift]
        out = depth.copy()
        near = other & ((moved < out) | ~person)
        out[near] = moved[near]
        return out

    v = _variant(d, tmp_path / "two", edit)
    assert _run([v, "--out", tmp_path / "o", "--init-joints", truth, "--no-global-fit", "--frames", "2"]) == 0
    z = np.load(tmp_path / "o" / "joints.npz")
    err = _mpjpe_mm(tmp_path / "o", truth)
    # either fitted to the subject, or the frames where it is not are said to be so
    assert np.all((err < 60) | (z["state"] != "ok")), (err, list(z["state"]))
