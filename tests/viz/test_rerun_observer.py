"""RerunObserver: a tiny scene over 3 frames, checked through the rerun CLI and read back.

The scene (2-camera rig, skeleton, images, masks, labels, depth, 2D/3D joints,
points, rays, lines, a mesh, textured quads, boxes, scalars, text) is logged to
a temporary ``.rrd``; ``rerun rrd verify`` must accept it, ``rerun rrd print``
must list the expected entities, and the values read back with
``rerun.chunk.RrdReader`` must equal what was reported.
"""

from __future__ import annotations

import re
import subprocess
import sys
import warnings
from pathlib import Path

import cv2
import numpy as np
import pytest
import rerun as rr

from toolkit.anthropometry.proportions import BodyProportions
from toolkit.cameras import Camera, Rig
from toolkit.errors import InputError, ToolkitError
from toolkit.observe import REPORT_KINDS, MultiObserver, RecordingObserver
from toolkit.skeleton import SKELETON_14
from toolkit.viz import RerunConfig, RerunObserver

#: Values go through float32 in the recording; positions are within 5 m of the origin.
FLOAT32_ATOL_M = 1e-5
#: Pixel coordinates up to 100 px through float32.
FLOAT32_ATOL_PX = 1e-4
#: Depth is stored as a millimetre PNG: rounding error is at most half a millimetre.
DEPTH_PNG_ATOL_M = 0.5e-3 + 1e-9
#: JPEG at quality 90 on a smooth gradient: mean absolute error in 8-bit levels.
JPEG_MEAN_ABS_ERR = 3.0

N_FRAMES = 3
SIZE = (80, 60)  # width, height: 4800 px, above the default compression threshold
MISSING_JOINT = 4  # l_wrist is NaN in frame 1


def rerun_cli() -> Path:
    """The rerun CLI installed next to the running interpreter."""
    cli = Path(sys.executable).parent / "rerun"
    assert cli.exists(), f"rerun CLI not found at {cli}"
    return cli


def gradient_image(frame: int, cam: int) -> np.ndarray:
    w, h = SIZE
    x = np.linspace(0, 1, w)[None, :]
    y = np.linspace(0, 1, h)[:, None]
    img = np.stack([200 * x + 0 * y, 200 * y + 0 * x, 50 + 20 * frame + 30 * cam + 0 * x * y], axis=-1)
    return np.round(img).astype(np.uint8)


def make_rig() -> Rig:
    return Rig((Camera.look_at("cam0", [3.0, -3.0, 1.5], [0, 0, 1.0], size=SIZE, fov_x_deg=60),
                Camera.look_at("cam1", [-3.0, -3.0, 1.5], [0, 0, 1.0], size=SIZE, fov_x_deg=60)))


def joints_at(frame: int) -> np.ndarray:
    J = BodyProportions.from_height(1.75).rest_pose() + np.array([0.1 * frame, 0.0, 0.0])
    if frame == 1:
        J[MISSING_JOINT] = np.nan
    return J


def depth_map(frame: int, rng: np.random.Generator) -> np.ndarray:
    d = rng.uniform(1.0, 4.0, (SIZE[1], SIZE[0]))
    d[0, :5] = 0.0  # no depth
    d[1, :5] = np.nan  # no depth either
    return d


def log_scene(obs, rig: Rig, rng: np.random.Generator) -> dict:
    """Report every kind over N_FRAMES frames; return the ground truth."""
    truth = {"depth": {}, "labels": {}, "quads": {}, "scalar": {}}
    obs.report("rig", rig=rig)
    obs.report("skeleton", skeleton=SKELETON_14)
    obs.report("mesh", name="ground", vertices=[[-2, -2, 0], [2, -2, 0], [2, 2, 0], [-2, 2, 0]],
               triangles=[[0, 1, 2], [0, 2, 3]], vertex_colors=[90, 90, 90], static=True)
    for f in range(N_FRAMES):
        obs.report("text", name="frames", text=f"frame {f}", frame=f)  # sets the timeline
        J = joints_at(f)
        for c, cam in enumerate(rig):
            obs.report("image", camera=cam.name, image=gradient_image(f, c))
            obs.report("image", camera=cam.name, image=gradient_image(f, c)[::5, ::5], name="thumb")
            obs.report("mask", camera=cam.name, mask=gradient_image(f, c)[..., 0] > 100, name="mask")
            labels = rng.integers(0, SKELETON_14.n_parts + 1, (SIZE[1], SIZE[0])).astype(np.uint8)
            truth["labels"][f, cam.name] = labels
            obs.report("labels", camera=cam.name, labels=labels, name="labels")
            depth = depth_map(f, rng)
            truth["depth"][f, cam.name] = depth
            obs.report("depth", camera=cam.name, depth=depth, name="depth")
            obs.report("joints2d", camera=cam.name, joints=cam.project(J), skeleton=SKELETON_14,
                       name="joints")
            obs.report("points2d", camera=cam.name, points=[[10.0, 10.0], [np.nan, 3.0]], name="features")
            obs.report("lines2d", camera=cam.name, strips=[[[0, 0], [10, 10], [20, 0]]], name="contour")
            obs.report("silhouette", camera=cam.name, points=[[12.0, 9.0], [14.0, 9.5]], residuals=[0.004, np.nan])
            obs.report("boxes2d", camera=cam.name, mins=[[5, 6]], sizes=[[20, 30]], labels=["subject"],
                       name="bbox")
        obs.report("joints3d", joints=J, skeleton=SKELETON_14, name="joints")
        obs.report("points3d", points=rng.normal(size=(5, 3)), colors=[255, 0, 0], name="cloud")
        obs.report("rays", origins=np.repeat(rig.centers, 2, axis=0), ends=np.nan_to_num(J[:4]), name="rays")
        obs.report("lines3d", strips=[np.array([[0, 0, 0], [0, 0, 1.0 + f]])], name="trajectory")
        textures = [rng.integers(0, 256, (8, 6, 4), dtype=np.uint8),  # RGBA and RGB, two sizes
                    rng.integers(0, 256, (5, 9, 3), dtype=np.uint8)]
        corners = rng.normal(size=(2, 4, 3))
        truth["quads"][f] = (corners, textures)
        obs.report("quads", corners=corners, textures=textures, name="billboards")
        obs.report("quads", corners=corners, colors=[[255, 0, 0], [0, 255, 0]], name="plain_quads")
        obs.report("scalar", name="fit/residual", value=0.5 * f + 0.25)
        obs.report("series", name="fit/score_per_sweep", values=np.linspace(0.2, 0.5 + f, 4))
        truth["scalar"][f] = 0.5 * f + 0.25
        obs.report("text", name="fit", text=f"frame {f} done", level="INFO")
        obs.report("depth_energy", stage="track", iteration=0, total=3.0 + f, blocks={"surface": 1.0 + f, "length": 2.0})
        obs.report("depth_move", move="swap_arms", won=f % 2 == 0, weight=0.5, energy=2.5)
        obs.report("depth_radial", angles_deg=np.arange(0.0, 360.0, 45.0), distances=np.linspace(0.2, 0.9, 8),
                   peaks=np.array([0, 4]))
    return truth


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    path = tmp_path_factory.mktemp("rrd") / "scene.rrd"
    rig = make_rig()
    seen = RecordingObserver()
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # rerun must not complain about any of the data
        with RerunObserver(path=path, application_id="toolkit_test") as obs:
            truth = log_scene(MultiObserver(obs, seen), rig, np.random.default_rng(7))
    return {"path": path, "rig": rig, "truth": truth, "kinds": seen.kinds}


def read_rows(path: Path) -> dict[str, list[tuple[int | None, dict]]]:
    """Entity path -> [(frame or None when static, {column: value})], frame-sorted."""
    rows: dict[str, list] = {}
    for chunk in rr.chunk.RrdReader(path).stream():
        rb = chunk.to_record_batch()
        cols = [n for n in rb.schema.names if ":" in n]
        data = {n: rb.column(n).to_pylist() for n in cols}
        frames = rb.column("frame").to_pylist() if "frame" in rb.schema.names else [None] * rb.num_rows
        for i in range(rb.num_rows):
            rows.setdefault(chunk.entity_path, []).append((frames[i], {n: data[n][i] for n in cols}))
    for v in rows.values():
        v.sort(key=lambda r: -1 if r[0] is None else r[0])
    return rows


@pytest.fixture(scope="module")
def rows(scene):
    return read_rows(scene["path"])


def column(rows, entity: str, name: str) -> list[tuple[int | None, object]]:
    out = [(f, d[name]) for f, d in rows[entity] if d.get(name) is not None]
    assert out, f"{entity} has no {name}"
    return out


# ------------------------------------------------------------------ the file
def test_scene_reports_every_kind(scene):
    assert set(REPORT_KINDS) <= scene["kinds"]


def test_every_report_kind_has_a_mapping():
    """Every kind declared in toolkit.observe has its own mapping, and every mapping is declared."""
    obs = RerunObserver()
    try:
        assert set(REPORT_KINDS) == obs.kinds
    finally:
        obs.close()


def test_depth_reports_become_metrics_and_logs(rows):
    energy = column(rows, "/metrics/depth_energy/track/surface", "Scalars:scalars")
    assert {f: v[0] for f, v in energy} == {f: 1.0 + f for f in range(N_FRAMES)}
    assert column(rows, "/metrics/depth_energy/track/total", "Scalars:scalars")[0][1] == [3.0]
    won = column(rows, "/metrics/depth_move/swap_arms/won", "Scalars:scalars")
    assert {f: v[0] for f, v in won} == {f: float(f % 2 == 0) for f in range(N_FRAMES)}
    bars = column(rows, "/metrics/depth_radial/distances", "BarChart:values")
    np.testing.assert_allclose(bars[0][1][0]["buffer"], np.linspace(0.2, 0.9, 8))
    assert column(rows, "/logs/depth_radial", "TextLog:text")[0][1] == ["peaks at 0 deg, 180 deg"]


def test_rerun_cli_verifies_the_recording(scene):
    res = subprocess.run([str(rerun_cli()), "rrd", "verify", str(scene["path"])],
                         capture_output=True, text=True, timeout=120)
    assert res.returncode == 0, res.stderr[-2000:]


def test_rerun_cli_lists_the_entity_tree(scene):
    res = subprocess.run([str(rerun_cli()), "rrd", "print", str(scene["path"])],
                         capture_output=True, text=True, timeout=120)
    assert res.returncode == 0, res.stderr[-2000:]
    comps: dict[str, set] = {}
    for m in re.finditer(r" - (/\S*) - data columns: \[([^\]]*)\]", res.stdout):
        comps.setdefault(m.group(1), set()).update(c.split(":")[0] for c in m.group(2).split())
    expected = {"/": "AnnotationContext", "/world": "ViewCoordinates", "/world/joints": "Points3D",
                "/world/cloud": "Points3D", "/world/rays": "LineStrips3D",
                "/world/trajectory": "LineStrips3D",
                "/world/ground": "Mesh3D", "/world/billboards": "Mesh3D", "/world/plain_quads": "Mesh3D",
                "/metrics/fit/residual": "Scalars", "/logs/fit": "TextLog"}
    for cam in ("cam0", "cam1"):
        img = f"/world/cams/{cam}/image"
        expected |= {f"/world/cams/{cam}": "Transform3D", img: "Pinhole", f"{img}/thumb": "Image",
                     f"{img}/mask": "SegmentationImage", f"{img}/labels": "SegmentationImage",
                     f"{img}/depth": "EncodedDepthImage", f"{img}/joints": "Points2D",
                     f"{img}/features": "Points2D", f"{img}/contour": "LineStrips2D",
                     f"{img}/bbox": "Boxes2D"}
        assert "EncodedImage" in comps[img]  # the 80x60 image is JPEG-compressed
    for entity, archetype in expected.items():
        assert archetype in comps.get(entity, set()), f"{entity}: {archetype} not in {comps.get(entity)}"
    assert "AnnotationContext" in comps["/world/cams/cam0/image/labels"]


# ------------------------------------------------------------ values back
def test_cameras_are_world_from_camera(scene, rows):
    for cam in scene["rig"]:
        (f, d), = rows[f"/world/cams/{cam.name}"]
        assert f is None  # static
        t = np.array(d["Transform3D:translation"][0])
        M = np.array(d["Transform3D:mat3x3"][0]).reshape(3, 3, order="F")  # stored column-major
        np.testing.assert_allclose(t, cam.center, atol=FLOAT32_ATOL_M)
        # A point in camera coordinates maps back to the world point it came from.
        Xw = np.array([0.3, -0.2, 1.1])
        Xc = cam.R @ Xw + cam.t
        np.testing.assert_allclose(M @ Xc + t, Xw, atol=FLOAT32_ATOL_M)
        pin = {k: v for _, dd in rows[f"/world/cams/{cam.name}/image"] for k, v in dd.items()
               if k.startswith("Pinhole")}
        K = np.array(pin["Pinhole:image_from_camera"][0]).reshape(3, 3, order="F")
        np.testing.assert_allclose(K, cam.K, rtol=1e-6)
        assert pin["Pinhole:resolution"][0] == list(map(float, cam.size))
        assert pin["Pinhole:camera_xyz"][0] == [3, 2, 5]  # Right, Down, Forward: OpenCV axes


def test_joints3d_per_frame_with_missing_joint_dropped(rows):
    pos = column(rows, "/world/joints", "Points3D:positions")
    ids = column(rows, "/world/joints", "Points3D:keypoint_ids")
    assert [f for f, _ in pos] == list(range(N_FRAMES))
    for (f, p), (_, k) in zip(pos, ids):
        J = joints_at(f)
        keep = np.all(np.isfinite(J), axis=1)
        assert k == list(np.flatnonzero(keep))
        np.testing.assert_allclose(np.array(p), J[keep], atol=FLOAT32_ATOL_M)
    assert len(ids[1][1]) == SKELETON_14.n_joints - 1 and MISSING_JOINT not in ids[1][1]


def test_joints2d_are_the_projections(scene, rows):
    for cam in scene["rig"]:
        pos = column(rows, f"/world/cams/{cam.name}/image/joints", "Points2D:positions")
        cls = column(rows, f"/world/cams/{cam.name}/image/joints", "Points2D:class_ids")
        for (f, p), (_, c) in zip(pos, cls):
            uv = cam.project(joints_at(f))
            keep = np.all(np.isfinite(uv), axis=1)
            np.testing.assert_allclose(np.array(p), uv[keep], atol=FLOAT32_ATOL_PX)
            assert set(c) == {1}


def test_skeleton_context_at_root_reaches_2d_and_3d_joints(rows):
    (_, d), = rows["/"]
    (ctx,) = d["AnnotationContext:context"]
    (cls,) = ctx  # one skeleton registered
    desc = cls["class_description"]
    assert cls["class_id"] == 1 and desc["info"]["label"] == SKELETON_14.name
    assert [k["label"] for k in desc["keypoint_annotations"]] == list(SKELETON_14.joint_names)
    conns = [(c["keypoint0"], c["keypoint1"]) for c in desc["keypoint_connections"]]
    assert conns == list(SKELETON_14.edges)
    # rerun uses the first context found walking up the path: for joints it must be the root.
    with_context = {e for e, r in rows.items() if any("AnnotationContext:context" in d for _, d in r)}
    for entity in ("/world/joints", "/world/cams/cam0/image/joints", "/world/cams/cam1/image/joints"):
        parts = entity.strip("/").split("/")
        ancestors = ["/" + "/".join(parts[:i]) for i in range(len(parts), 0, -1)]
        assert not with_context & set(ancestors), f"{entity} would not see the skeleton context"


def test_part_labels_keep_ids_and_names(scene, rows):
    (_, d), = [r for r in rows["/world/cams/cam0/image/labels"] if r[0] is None]
    ctx = d["AnnotationContext:context"][0]
    assert [c["class_id"] for c in ctx] == list(range(SKELETON_14.n_parts + 1))
    assert [c["class_description"]["info"]["label"] for c in ctx[1:]] == list(SKELETON_14.part_names)
    for f, buf in column(rows, "/world/cams/cam0/image/labels", "SegmentationImage:buffer"):
        expected = scene["truth"]["labels"][f, "cam0"]
        np.testing.assert_array_equal(np.array(buf, np.uint8).reshape(expected.shape), expected)


def test_depth_png_round_trip(scene, rows):
    blobs = column(rows, "/world/cams/cam1/image/depth", "EncodedDepthImage:blob")
    meter = column(rows, "/world/cams/cam1/image/depth", "EncodedDepthImage:meter")
    for (f, blob), (_, m) in zip(blobs, meter):
        png = cv2.imdecode(np.array(blob, np.uint8), cv2.IMREAD_UNCHANGED)
        assert png.dtype == np.uint16
        got = png / m[0]
        truth = scene["truth"]["depth"][f, "cam1"]
        valid = np.isfinite(truth) & (truth > 0)
        np.testing.assert_allclose(got[valid], truth[valid], atol=DEPTH_PNG_ATOL_M)
        assert np.all(got[~valid] == 0)


def test_images_compressed_when_large_raw_when_small(rows):
    for f, blob in column(rows, "/world/cams/cam0/image", "EncodedImage:blob"):
        bgr = cv2.imdecode(np.array(blob, np.uint8), cv2.IMREAD_COLOR)
        rgb = cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB)
        err = np.abs(rgb.astype(float) - gradient_image(f, 0)).mean()
        assert err < JPEG_MEAN_ABS_ERR
    for f, buf in column(rows, "/world/cams/cam0/image/thumb", "Image:buffer"):
        thumb = gradient_image(f, 0)[::5, ::5]
        np.testing.assert_array_equal(np.array(buf, np.uint8).reshape(thumb.shape), thumb)


def test_quad_texcoords_address_each_texture(scene, rows):
    fmt = column(rows, "/world/billboards", "Mesh3D:albedo_texture_format")
    buf = column(rows, "/world/billboards", "Mesh3D:albedo_texture_buffer")
    uvs = column(rows, "/world/billboards", "Mesh3D:vertex_texcoords")
    verts = column(rows, "/world/billboards", "Mesh3D:vertex_positions")
    for (f, fm), (_, b), (_, uv), (_, v) in zip(fmt, buf, uvs, verts):
        corners, textures = scene["truth"]["quads"][f]
        np.testing.assert_allclose(np.array(v), corners.reshape(-1, 3), atol=FLOAT32_ATOL_M)
        W, H = fm[0]["width"], fm[0]["height"]
        atlas = np.array(b, np.uint8).reshape(H, W, 3)
        uv = np.array(uv).reshape(-1, 4, 2)
        for q, tex in enumerate(textures):
            h, w = tex.shape[:2]
            # texel centres under the top-left and bottom-right corners
            x0, y0 = np.round(uv[q, 0] * [W, H] - 0.5).astype(int)
            x1, y1 = np.round(uv[q, 2] * [W, H] - 0.5).astype(int)
            assert (x1 - x0 + 1, y1 - y0 + 1) == (w, h)
            np.testing.assert_array_equal(atlas[y0:y1 + 1, x0:x1 + 1], tex[..., :3])


def test_scalars_on_frame_timeline(scene, rows):
    got = column(rows, "/metrics/fit/residual", "Scalars:scalars")
    assert {f: v[0] for f, v in got} == scene["truth"]["scalar"]


def test_static_report_has_no_time(rows):
    assert all(f is None for f, _ in rows["/world/ground"])


# ------------------------------------------------------------ behaviour
def test_unknown_kind_is_logged_generically(tmp_path):
    path = tmp_path / "generic.rrd"
    with RerunObserver(path=path) as obs:
        obs.report("mystery", frame=4, score=0.75, grid=np.arange(6.0).reshape(2, 3), mask=np.ones(3, bool),
                   note="hello", obj=object(), empty=np.zeros((0, 2)), ragged=[[1, 2], [3]], z=1 + 2j)
    rows = read_rows(path)
    (f, d), = rows["/metrics/mystery/score"]
    assert f == 4 and d["Scalars:scalars"] == [0.75]
    assert "Tensor:data" in rows["/reports/mystery/grid"][0][1]
    assert "/reports/mystery/mask" in rows
    (_, log), = rows["/logs/reports/mystery"]
    text = log["TextLog:text"][0]
    assert "note='hello'" in text and "grid=array(2, 3)" in text and "empty=" in text
    assert "ragged=[[1, 2], [3]]" in text and "z=(1+2j)" in text


def test_frame_field_sets_the_timeline(tmp_path):
    path = tmp_path / "frames.rrd"
    with RerunObserver(path=path) as obs:
        obs.report("scalar", name="a", value=1.0, frame=7)
        obs.report("scalar", name="a", value=2.0)  # frame 7 stays set
        obs.report("scalar", name="a", value=3.0, frame=9)
        assert obs.frame == 9
        obs.set_frame(np.int64(2))
        obs.report("scalar", name="a", value=4.0)
    got = read_rows(path)["/metrics/a"]
    assert [(f, d["Scalars:scalars"][0]) for f, d in got] == [(2, 4.0), (7, 1.0), (7, 2.0), (9, 3.0)]


@pytest.mark.parametrize("frame", [1.5, "x", None])
def test_bad_frame_raises(frame):
    with RerunObserver() as obs:
        with pytest.raises(InputError, match="frame"):
            obs.set_frame(frame)


@pytest.mark.parametrize("kind, data, where", [
    ("joints3d", {"joints": np.zeros((14, 2))}, "joints"),
    ("joints3d", {"joints": np.zeros((13, 3)), "skeleton": SKELETON_14}, "joints"),
    ("joints2d", {"joints": np.zeros((14, 2))}, "camera"),
    ("image", {"camera": "cam0", "image": np.zeros((4, 4, 2), np.uint8)}, "image"),
    ("depth", {"camera": "cam0", "depth": np.zeros((4, 4), np.uint16)}, "depth"),
    ("mesh", {"vertices": np.zeros((3, 3)), "triangles": [[0, 1, 3]]}, "triangles"),
    ("quads", {"corners": np.zeros((2, 4, 3)), "textures": [np.zeros((2, 2, 3), np.uint8)]}, "textures"),
    ("scalar", {"name": "x"}, "value"),
    ("rays", {"origins": np.zeros((2, 3)), "ends": np.zeros((3, 3))}, "ends"),
])
def test_bad_fields_of_known_kinds_raise(kind, data, where):
    with RerunObserver() as obs:
        with pytest.raises(InputError, match=where):
            obs.report(kind, **data)


def test_unwritable_parent_raises_naming_the_path_before_any_work(tmp_path):
    blocker = tmp_path / "not_a_dir"
    blocker.write_text("a file where a directory should be")
    path = blocker / "run.rrd"
    with pytest.raises(InputError) as err:
        RerunObserver(path=path)
    assert str(path) in str(err.value)
    assert not path.exists()


def test_directory_as_path_raises(tmp_path):
    with pytest.raises(InputError, match="existing directory") as err:
        RerunObserver(path=tmp_path)
    assert str(tmp_path) in str(err.value)


def test_missing_parent_directories_are_created(tmp_path):
    path = tmp_path / "a" / "b" / "run.rrd"
    with RerunObserver(path=path) as obs:
        obs.report("text", name="x", text="hi")
    assert path.stat().st_size > 0


def test_reporting_after_close_raises(tmp_path):
    obs = RerunObserver(path=tmp_path / "closed.rrd")
    obs.close()
    obs.close()  # idempotent
    with pytest.raises(ToolkitError, match="closed"):
        obs.report("scalar", name="x", value=1.0)


def test_uses_an_explicit_stream_not_the_global_one(tmp_path):
    before = rr.get_global_data_recording()
    rec = rr.RecordingStream("toolkit_test_explicit")
    with RerunObserver(rec, path=tmp_path / "explicit.rrd") as obs:
        assert obs.recording is rec
        obs.report("scalar", name="x", value=1.0)
    assert rr.get_global_data_recording() is before
    assert "/metrics/x" in read_rows(tmp_path / "explicit.rrd")


def test_compression_keeps_recordings_small(tmp_path):
    """A camera-like image (gradient plus sensor noise): JPEG beats rerun's own chunk compression."""
    w, h = 320, 240
    x = np.linspace(0, 255, w)[None, :, None]
    y = np.linspace(0, 255, h)[:, None, None]
    noise = np.random.default_rng(0).normal(0.0, 8.0, (h, w, 3))
    img = np.clip((x + y) / 2 + noise, 0, 255).astype(np.uint8)
    sizes = {}
    for compress in (True, False):
        path = tmp_path / f"img_{compress}.rrd"
        with RerunObserver(path=path, config=RerunConfig(compress_images=compress)) as obs:
            for f in range(3):
                obs.report("image", camera="c", image=img, frame=f)
        sizes[compress] = path.stat().st_size
    assert sizes[True] < sizes[False] / 5


def test_skeleton_class_id_conflict_raises():
    from toolkit.skeleton import SKELETON_17

    with RerunObserver() as obs:
        obs.report("skeleton", skeleton=SKELETON_14, class_id=3)
        with pytest.raises(InputError, match="class_id"):
            obs.report("skeleton", skeleton=SKELETON_17, class_id=3)
        obs.report("joints3d", joints=np.zeros((17, 3)), skeleton=SKELETON_17)  # gets a fresh id
        assert obs.skeleton_class_ids == {SKELETON_14.name: 3, SKELETON_17.name: 4}


def test_alternative_encodings(tmp_path):
    """Soft mattes, small depth maps, grey images, wide label ids and untextured input."""
    path = tmp_path / "alt.rrd"
    matte = np.linspace(0, 1, 12).reshape(3, 4)
    depth = np.array([[1.25, 0.0], [np.nan, 2.5]])
    labels = np.array([[0, 300], [2, 1]])
    with RerunObserver(path=path) as obs:
        obs.report("mask", camera="c", mask=matte, name="matte", frame=0)
        obs.report("depth", camera="c", depth=depth, name="depth")
        obs.report("image", camera="c", image=np.full((100, 100), 7, np.uint8), name="grey")
        obs.report("image", camera="c", image=np.zeros((100, 100, 4), np.uint8), name="rgba")
        obs.report("labels", camera="c", labels=labels, name="labels")
        obs.report("mesh", name="gone", vertices=np.zeros((0, 3)), triangles=np.zeros((0, 3), int))
    rows = read_rows(path)
    (_, d), = rows["/world/cams/c/image/matte"]
    np.testing.assert_array_equal(np.array(d["Image:buffer"][0], np.uint8).reshape(3, 4),
                                  np.round(matte * 255).astype(np.uint8))
    (_, d), = rows["/world/cams/c/image/depth"]
    got = np.frombuffer(bytes(d["DepthImage:buffer"][0]), np.float32).reshape(2, 2)
    np.testing.assert_array_equal(got, [[1.25, 0.0], [0.0, 2.5]])
    assert d["DepthImage:meter"] == [1.0]
    (_, d), = rows["/world/cams/c/image/grey"]
    assert "EncodedImage:blob" in d
    (_, d), = rows["/world/cams/c/image/rgba"]
    assert "Image:buffer" in d  # JPEG has no alpha: stored raw
    (_, d), = [r for r in rows["/world/cams/c/image/labels"] if r[0] is not None]
    wide = np.frombuffer(bytes(d["SegmentationImage:buffer"][0]), np.uint16).reshape(2, 2)
    np.testing.assert_array_equal(wide, labels)  # ids above 255 need 16 bits
    (_, d), = rows["/world/gone"]
    assert any(k.startswith("Clear") for k in d)
