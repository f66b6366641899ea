"""The soft-body run and recipe (issue 18): end to end on a tiny depth dataset, and bad input."""

from __future__ import annotations

import json

import numpy as np
import pytest

from recipes import fit_soft_body
from toolkit.errors import InputError
from toolkit.pipeline.soft_body_sources import joints14_from_control13, read_clicks, read_init_joints
from toolkit.synthetic.generator import build_scene, render_depth_dataset
from toolkit.synthetic.spec import parse_spec

SPEC = """seed = 4
frames = 4
fps = 30
[subject]
height_m = 1.74
motion = "idle"
[cameras]
count = 1
layout = "studio"
resolution = [160, 120]
[depth_camera]
resolution = [320, 240]
noise = true
environment = "floor"
distance_m = 3.0
"""


@pytest.fixture(scope="module")
def depth_dataset(tmp_path_factory):
    root = tmp_path_factory.mktemp("sb_depth")
    spec = parse_spec(SPEC, "test_soft_body")
    render_depth_dataset(spec, root)
    return root, build_scene(spec)


@pytest.mark.slow
def test_recipe_end_to_end_on_depth_frames(depth_dataset, tmp_path, capsys):
    root, scene = depth_dataset
    out = tmp_path / "fit"
    assert fit_soft_body.main([str(root), "--out", str(out), "--quiet", "--meshes"]) == 0
    printed = capsys.readouterr().out
    assert "fitted 4 frames (depth)" in printed and "recording.rrd" in printed
    z = np.load(out / "joints.npz")
    assert z["joints"].shape == (4, 14, 3) and list(z["names"])[:2] == ["head", "neck"]
    assert z["joints_tracking"].shape == (4, 14, 3) and z["params"].shape == (4, 47)
    err = np.linalg.norm(z["joints"] - scene.joints[:4], axis=-1)
    assert np.median(err) < 0.08  # a standing person, four frames: the fit stays on the body
    model = json.loads((out / "body_model.json").read_text())
    assert set(model["lengths"]) >= {"torso", "l_thigh"} and len(model["bone_lengths"]) == 13
    assert len(model["metaballs"]) > 20 and {"centre", "radii", "weight"} <= set(model["metaballs"][0])
    assert sorted(p.name for p in (out / "meshes").glob("*.ply")) == [f"{t:06d}.ply" for t in range(4)]
    assert (out / "recording.rrd").stat().st_size > 10_000
    _layout_shows_what_was_recorded(out / "recording.rrd")
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["frames"] == 4 and sum(metrics["states"].values()) == 4


def _layout_shows_what_was_recorded(path) -> None:
    """The recording's soft-body layout: every view's origin holds data (no view left empty by a renamed
    report), the lengths' bar charts among them."""
    import rerun as rr

    reader = rr.chunk.RrdReader(path)
    (bp,) = reader.blueprints()
    origins = set()
    for chunk in reader.stream(store=bp):
        rb = chunk.to_record_batch()
        if "ViewBlueprint:space_origin" in rb.schema.names:
            origins.add(rb.column("ViewBlueprint:space_origin").to_pylist()[-1][0].strip("/"))
    data = {c.entity_path.strip("/") for c in rr.chunk.RrdReader(path).stream()}
    assert "metrics/softbody/global/lengths/l_thigh" in origins and "world" in origins
    empty = {o for o in origins if not any(d == o or d.startswith(o + "/") for d in data)}
    assert not empty, f"views without data: {sorted(empty)}"


def test_stereo_needs_initial_joints_and_bad_files_are_named(tmp_path, capsys):
    from toolkit.io import DatasetWriter
    from toolkit.synthetic.rigs import make_rig

    root = tmp_path / "tri"
    w = DatasetWriter(root, 25.0)
    rig = make_rig("trinocular", 3, (64, 48), 1.75, 0)
    w.write_calibration(rig)
    for cam in rig:
        w.write_frame(cam.name, 0, np.zeros((48, 64, 3), np.uint8))
        w.write_background(cam.name, np.zeros((48, 64, 3), np.uint8))
    w.close()
    assert fit_soft_body.main([str(root), "--out", str(tmp_path / "o"), "--quiet"]) == 2
    assert "--init-joints / --clicks" in capsys.readouterr().err
    bad = tmp_path / "bad.npz"
    np.savez(bad, joints=np.zeros((3, 13, 3)))
    with pytest.raises(InputError, match="bad.npz: joints"):
        read_init_joints(bad, 0)
    with pytest.raises(InputError, match="camera_a"):
        read_clicks(bad, rig)
    assert fit_soft_body.main([str(tmp_path / "missing"), "--out", str(tmp_path / "o2"), "--quiet"]) == 2


def test_control_points_back_to_joints():
    from toolkit.body.control_points import control_points

    scene = build_scene(parse_spec(SPEC, "x"))
    j14 = scene.joints[0]
    j13, _ = control_points(j14, 1.74)
    back = joints14_from_control13(j13, 1.74)
    assert np.abs(back - j14).max() < 0.03  # the neck comes back from a median shoulder drop


@pytest.mark.realdata
@pytest.mark.slow
def test_real_kinect_stills_are_fitted(tmp_path):
    """Two real Kinect v1 stills, each from its own depth-tracker skeleton: the surface lies on the user's points."""
    from tests.depth.conftest import realdata_root

    root = realdata_root() / "kinect_depth"
    if not root.is_dir():
        pytest.skip(f"real Kinect frames not found at {root}")
    out = tmp_path / "kinect"
    assert fit_soft_body.main([str(root), "--out", str(out), "--independent", "--frames", "2", "--quiet",
                               "--no-recording", "--images", str(out / "img")]) == 0
    z = np.load(out / "joints.npz")
    assert list(z["state"]) == ["ok", "ok"] and np.isfinite(z["joints"]).all()
    head, neck = z["joints"][:, 0], z["joints"][:, 1]
    assert (head[:, 2] > neck[:, 2]).all()  # upright in the level frame
    assert len(list((out / "img").glob("softbody_*.png"))) == 2
