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
    frame 2: no depth at all.  The global fit runs over the good frame; the empty frames' poses are held
    (``params``) but not written as tracked (joints NaN, not trusted)."""
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
    assert list(z["trusted"]) == [True, False, False]
    assert np.isfinite(z["joints"][0]).all() and np.isnan(z["joints"][1:]).all()
    assert np.isfinite(z["params"]).all()
    m = json.loads((tmp_path / "o" / "metrics.json").read_text())
    assert m["states"] == {"empty": 2, "ok": 1}
    assert m["trusted_frames"] == [0] and m["lost_frames"] == [1, 2]
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


def _second_person(shift):
    """A depth edit: a second copy of the person ``shift`` pixels to the side (about 1 cm per pixel at
    3 m with this camera), the nearer of the two where they overlap."""
    def edit(t, depth, bg):
        person = (depth != bg) & (depth > 0)
        other, moved = np.zeros_like(person), np.zeros_like(depth)
        if shift > 0:
            other[:, shift:], moved[:, shift:] = person[:, :-shift], depth[:, :-shift]
        else:
            other[:, :shift], moved[:, :shift] = person[:, -shift:], depth[:, -shift:]
        out = depth.copy()
        near = other & ((moved < out) | ~person)
        out[near] = moved[near]
        return out
    return edit


@pytest.mark.parametrize("shift", [45, -45, 90])
def test_second_person_beside_the_subject(tmp_path, dataset, shift):
    """A second person 0.45 m to either side, touching the subject (one foreground blob), or 0.9 m
    away (a blob of its own).  Before: touching, it joined the cloud and pulled the fit sideways
    frame after frame, every state "ok" (MPJPE 146, 201, 223 mm at +45 px; 193, 390, 349 mm at
    -45 px); standing apart, the depth source kept one blob of the two, here the other person's:
    every frame "empty"."""
    d, truth = dataset
    v = _variant(d, tmp_path / "two", _second_person(shift))
    assert _run([v, "--out", tmp_path / "o", "--init-joints", truth, "--no-global-fit"]) == 0
    z = np.load(tmp_path / "o" / "joints.npz")
    err = _mpjpe_mm(tmp_path / "o", truth)
    assert list(z["state"]) == ["ok"] * 3, (err, list(z["state"]))
    assert np.all(err < 60), err


def test_second_person_overlapping_the_subject_is_crowded(tmp_path, dataset):
    """A second person 0.2 m to the side: the two overlap in the view and all of the other lies within
    the tracker's gate.  The first frame cannot tell them apart: state "crowded", fitted on the points
    near the model only; from then on the other's points are known and left out.  Before: "ok" with
    MPJPE 92, 131, 137 mm."""
    d, truth = dataset
    v = _variant(d, tmp_path / "overlap", _second_person(20))
    assert _run([v, "--out", tmp_path / "o", "--init-joints", truth, "--no-global-fit"]) == 0
    z = np.load(tmp_path / "o" / "joints.npz")
    err = _mpjpe_mm(tmp_path / "o", truth)
    assert z["state"][0] == "crowded", list(z["state"])
    assert not z["trusted"][0] and np.isnan(err[0])   # crowded: not reported as tracked
    assert z["trusted"][1:].all() and np.all(err[1:] < 60), err
