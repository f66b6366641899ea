"""Synthetic marker captures: files, detections, occlusion, markers on the skin and rigid, bad specs."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest

from toolkit.anthropometry import BodyProportions
from toolkit.body.model import BodyModel, BodyShape
from toolkit.errors import InputError
from toolkit.io import read_calibration_toml, write_calibration
from toolkit.io.marker_files import read_detection_truth, read_marker_detections, read_marker_truth
from toolkit.markers import MARKER_SETS, get_marker_set, load_marker_capture
from toolkit.markers.marker_sets import MARKER_RADIUS_M, PLATE_STANDOFF_M, SEGMENT_ORIGINS, SEGMENT_PARTS
from toolkit.motion import synthesize_motion
from toolkit.skeleton import SKELETON_14
from toolkit.synthetic.marker_capture import (
    body_occlusion,
    build_marker_scene,
    generate_marker_capture,
    soft_tissue_offsets,
)
from toolkit.synthetic.spec import parse_spec

SPEC = """
seed = 5
frames = 240
fps = 30
[subject]
height_m = 1.72
motion = "rom"
[markers]
set = "{set}"
noise_px = 0.5
occlusion = 0.1
ghosts = 2.0
calibration_error_px = {cal}
[markers.cameras]
count = 6
"""
#: Ghost counts are Poisson: the total may differ from the mean by this many standard deviations.
POISSON_SIGMAS = 4.0
#: The achieved share of missed blobs may differ from the asked one by this much (bursts of 8 frames
#: over 240 frames x 6 cameras x 39 markers leave about 2000 independent runs).
OCCLUSION_TOL = 0.03
#: A blob lies within this many noise standard deviations of its marker's true projection.
NOISE_SIGMAS = 5.0
#: Marker centres sit a marker radius off the mesh skin; the mesh of a moving body (the torso is
#: one capsule bent between pelvis and thorax, the hands and feet keep the body's lateral axis)
#: and the soft-tissue motion move them by up to this much, metres.
SKIN_TOL_M = 0.012
#: Share of (camera, frame, marker) where the occlusion test may disagree with a ray cast
#: against the full mesh (thin-volume approximations at grazing rays).
OCCLUSION_MODEL_DISAGREEMENT = 0.04


@pytest.fixture(scope="module")
def capture(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("markers") / "rom"
    spec = parse_spec(SPEC.format(set="plug-in-gait", cal=0.0), "rom.toml")
    generate_marker_capture(spec, out)
    return out


@pytest.fixture(scope="module")
def scene():
    return build_marker_scene(parse_spec(SPEC.format(set="plug-in-gait", cal=0.0), "rom.toml"))


def test_files_and_shapes(capture):
    cap = load_marker_capture(capture)
    assert cap.n_frames == 240 and cap.fps == 30.0 and len(cap.rig) == 6
    truth = read_marker_truth(capture / "groundtruth" / "markers3d.npz")
    M = len(truth["labels"])
    assert truth["labels"] == MARKER_SETS["plug-in-gait"].labels
    assert truth["positions"].shape == (240, M, 3) and np.isfinite(truth["positions"]).all()
    assert len(truth["segment"]) == M
    joints = np.load(capture / "groundtruth" / "joints3d.npz")
    assert joints["joints"].shape == (240, 14, 3)
    for cam in cap.rig:
        c, f, size = read_marker_detections(capture / "markers" / "detections" / f"{cam.name}.npz")
        assert c.shape == (len(f), 2) and size == cam.size and np.all(np.diff(f) >= 0)
        assert cap.detections(cam.name, 100).shape[1] == 2
        who = read_detection_truth(capture / "groundtruth" / "marker_detections" / f"{cam.name}.npz", M)
        assert who.shape == f.shape
    true_rig = read_calibration_toml(capture / "groundtruth" / "calibration.toml")
    assert np.allclose(true_rig[0].cam_from_world, cap.rig[0].cam_from_world)   # no calibration error asked


def test_blobs_are_noisy_projections_and_ghosts_are_minus_one(capture):
    cap = load_marker_capture(capture)
    X = read_marker_truth(capture / "groundtruth" / "markers3d.npz")["positions"]
    n_ghosts = 0
    for cam in cap.rig:
        c, f, _ = read_marker_detections(capture / "markers" / "detections" / f"{cam.name}.npz")
        who = read_detection_truth(capture / "groundtruth" / "marker_detections" / f"{cam.name}.npz")
        real = who >= 0
        err = np.linalg.norm(c[real] - cam.project(X[f[real], who[real]]), axis=1)
        assert err.max() < NOISE_SIGMAS * 0.5 * np.sqrt(2)
        assert 0.3 < np.sqrt(np.mean(err ** 2) / 2) < 0.7          # the asked 0.5 px per axis
        # a marker is seen at most once per camera and frame
        pairs = f[real] * 1000 + who[real]
        assert len(np.unique(pairs)) == len(pairs)
        n_ghosts += int((who == -1).sum())
    mean = 2.0 * 6 * 240
    assert abs(n_ghosts - mean) < POISSON_SIGMAS * np.sqrt(mean)


def test_missed_share_near_the_asked_value(capture, scene):
    visible = 0
    seen = 0
    hidden = body_occlusion(scene.rig, scene.markers, scene.joints, scene.rotations, scene.shape)
    for c, cam in enumerate(scene.rig):
        uv = cam.project(scene.markers)
        visible += int((cam.in_image(uv) & np.isfinite(uv).all(-1) & ~hidden[c]).sum())
        who = read_detection_truth(capture / "groundtruth" / "marker_detections" / f"{cam.name}.npz")
        seen += int((who >= 0).sum())
    assert abs((1 - seen / visible) - 0.1) < OCCLUSION_TOL
    # and the body hides a good share of the markers from each camera (a person is not transparent)
    assert 0.15 < hidden.mean() < 0.5


def test_misses_come_in_bursts(capture):
    cap = load_marker_capture(capture)
    who = read_detection_truth(capture / "groundtruth" / "marker_detections" / "cam00.npz")
    seen = np.zeros((cap.n_frames, 39), bool)
    seen[cap.frames["cam00"][who >= 0], who[who >= 0]] = True
    # runs of misses between sightings: mostly longer than a frame
    gaps = []
    for m in range(39):
        on = np.flatnonzero(seen[:, m])
        gaps += list(np.diff(on)[np.diff(on) > 1] - 1)
    assert np.median(gaps) >= 2


def test_occlusion_agrees_with_the_mesh(scene):
    import open3d as o3d

    hidden = body_occlusion(scene.rig, scene.markers, scene.joints, scene.rotations, scene.shape)
    body = BodyModel(scene.shape, rng=0)
    disagree = n = 0
    for t in (20, 90, 160, 230):
        mesh = body.mesh(scene.joints[t])
        rc = o3d.t.geometry.RaycastingScene()
        rc.add_triangles(o3d.core.Tensor(mesh.vertices.astype(np.float32)),
                         o3d.core.Tensor(mesh.triangles.astype(np.uint32)))
        for c, cam in enumerate(scene.rig):
            v = scene.markers[t] - cam.center
            dist = np.linalg.norm(v, axis=1)
            rays = np.hstack([np.tile(cam.center, (len(v), 1)), v / dist[:, None]]).astype(np.float32)
            t_hit = rc.cast_rays(o3d.core.Tensor(rays))["t_hit"].numpy()
            disagree += int(((t_hit < dist - 0.02) != hidden[c, t]).sum())
            n += len(v)
    assert disagree / n < OCCLUSION_MODEL_DISAGREEMENT


@pytest.mark.parametrize("set_name", sorted(MARKER_SETS))
def test_markers_sit_on_the_skin(set_name):
    import open3d as o3d

    p = BodyProportions.from_height(1.68)
    shape = BodyShape(p)
    m = synthesize_motion("walk", p, 40, 50.0, rng=2)
    mset = get_marker_set(set_name)
    X = mset.positions(m.joints, shape, pose=m.pose)
    body = BodyModel(shape, rng=0)
    plate = np.array([pl.plate is not None for pl in mset.placements])
    part_id = {name: i + 1 for i, name in enumerate(SKELETON_14.part_names)}
    for t in (0, 25):
        mesh = body.mesh(m.joints[t])
        d = np.empty(mset.n_markers)
        for seg in mset.segment_names:   # distance to the skin of the marker's own segment
            keep = np.isin(mesh.triangle_parts, [part_id[n] for n in SEGMENT_PARTS[seg]])
            rc = o3d.t.geometry.RaycastingScene()
            rc.add_triangles(o3d.core.Tensor(mesh.vertices.astype(np.float32)),
                             o3d.core.Tensor(mesh.triangles[keep].astype(np.uint32)))
            idx = mset.markers_of(seg)
            d[idx] = rc.compute_distance(o3d.core.Tensor(X[t, idx].astype(np.float32))).numpy()
        skin = d[~plate]
        assert np.all(np.abs(skin - MARKER_RADIUS_M) < SKIN_TOL_M), (t, dict(zip(mset.labels, d.round(3))))
        if plate.any():   # plates stand off the skin (their corners over a curved limb a little more)
            off = d[plate] - MARKER_RADIUS_M
            assert np.all((off > PLATE_STANDOFF_M - 0.005) & (off < PLATE_STANDOFF_M + 0.03)), off


def test_markers_rigid_with_their_segment_up_to_soft_tissue():
    p = BodyProportions.from_height(1.8)
    m = synthesize_motion("rom", p, 300, 30.0, rng=4)
    mset = get_marker_set("cluster")
    J = {n: i for i, n in enumerate(("head", "neck", "l_shoulder", "l_elbow", "l_wrist", "r_shoulder", "r_elbow",
                                     "r_wrist", "l_hip", "l_knee", "l_ankle", "r_hip", "r_knee", "r_ankle"))}

    def origin_distance(X):
        out = np.empty(X.shape[:2])
        for i, seg in enumerate(mset.segments):
            o = m.joints[:, [J[n] for n in SEGMENT_ORIGINS[seg]]].mean(1)
            out[:, i] = np.linalg.norm(X[:, i] - o, axis=-1)
        return out

    exact = mset.positions(m.joints, BodyShape(p), pose=m.pose, ankle=m.ankle)
    d = origin_distance(exact)
    np.testing.assert_allclose(d, np.broadcast_to(d[0], d.shape), atol=1e-9)   # rigid: constant distances
    sta = 0.003
    off = soft_tissue_offsets(mset, 300, 30.0, sta, np.random.default_rng(0))
    moved = mset.positions(m.joints, BodyShape(p), pose=m.pose, ankle=m.ankle, local_offsets=off)
    dev = np.linalg.norm(moved - exact, axis=-1)
    assert 0.5 * sta < np.sqrt(np.mean(dev ** 2) / 3) < 1.5 * sta
    assert dev.max() < 6 * sta
    # smooth in time (a few Hz): frame-to-frame steps in the segment frame of a few mm at 30 fps,
    # where white noise of the same size would jump by up to 5 sigma
    assert np.linalg.norm(np.diff(off, axis=0), axis=-1).max() < 2 * sta
    # the markers of one plate move together (the plate is rigid)
    i, j = mset.index("RTH1"), mset.index("RTH3")
    np.testing.assert_allclose(np.linalg.norm(moved[:, i] - moved[:, j], axis=-1),
                               np.linalg.norm(exact[:, i] - exact[:, j], axis=-1), atol=1e-9)


def test_calibration_error_is_in_the_measured_rig(tmp_path):
    spec = parse_spec(SPEC.format(set="cluster", cal=2.0).replace("frames = 240", "frames = 20"), "c.toml")
    info = generate_marker_capture(spec, tmp_path / "c")
    measured = load_marker_capture(tmp_path / "c").rig
    true = read_calibration_toml(tmp_path / "c" / "groundtruth" / "calibration.toml")
    X = read_marker_truth(tmp_path / "c" / "groundtruth" / "markers3d.npz")["positions"].reshape(-1, 3)
    errs = [np.nanmean(np.linalg.norm(a.project(X) - b.project(X), axis=-1)) for a, b in zip(measured, true)]
    assert np.allclose(errs, 2.0, rtol=0.25) and info["marker_set"] == "cluster"


def test_same_seed_same_capture(tmp_path, capture):
    spec = parse_spec(SPEC.format(set="plug-in-gait", cal=0.0), "rom.toml")
    generate_marker_capture(spec, tmp_path / "again")
    for sub in ("markers/detections/cam03.npz", "groundtruth/marker_detections/cam03.npz",
                "groundtruth/markers3d.npz"):
        a, b = np.load(capture / sub), np.load(tmp_path / "again" / sub)
        for k in a.files:
            np.testing.assert_array_equal(a[k], b[k])


@pytest.mark.parametrize("table, field", [
    ('set = "vicon"', "markers.set"),
    ("cameras = 2", "markers.cameras.count"),
    ("[markers.cameras]\ncount = 2", "markers.cameras.count"),
    ("[markers.cameras]\nradius_m = 7.5", "markers.cameras.radius_m"),
    ("[markers.cameras]\nresolution = [1281, 1024]", "markers.cameras.resolution"),
    ("[markers.cameras]\nzoom = 2", "markers.cameras.zoom"),
    ("noise_px = -0.5", "markers.noise_px"),
    ("occlusion = 0.95", "markers.occlusion"),
    ('ghosts = "many"', "markers.ghosts"),
    ("occlusion_burst_frames = 0.5", "markers.occlusion_burst_frames"),
    ("colour = 1", "markers.colour"),
])
def test_bad_marker_fields_are_named(table, field):
    text = f"seed = 1\nframes = 5\nfps = 50\n[subject]\nheight_m = 1.7\nmotion = 'walk'\n[markers]\n{table}\n"
    with pytest.raises(InputError, match=f"bad.toml: {field}"):
        parse_spec(text, "bad.toml")


def test_a_marker_capture_has_no_cameras_table():
    text = ("seed = 1\nframes = 5\nfps = 50\n[subject]\nheight_m = 1.7\nmotion = 'walk'\n[markers]\n"
            "[cameras]\ncount = 3\nlayout = 'studio'\nresolution = [640, 480]\n")
    with pytest.raises(InputError, match="bad.toml: cameras"):
        parse_spec(text, "bad.toml")


def test_reader_refuses_fewer_than_three_cameras_and_missing_files(tmp_path, capture):
    bad = tmp_path / "two"
    shutil.copytree(capture, bad)
    rig = read_calibration_toml(bad / "markers" / "calibration.toml")
    from toolkit.cameras import Rig

    write_calibration(bad / "markers" / "calibration.toml", Rig(tuple(rig)[:2]),
                      metadata={"fps": 30.0, "n_frames": 240})
    with pytest.raises(InputError, match="at least 3 cameras"):
        load_marker_capture(bad)
    gone = tmp_path / "gone"
    shutil.copytree(capture, gone)
    (gone / "markers" / "detections" / "cam02.npz").unlink()
    with pytest.raises(InputError, match="cam02.npz"):
        load_marker_capture(gone)
    with pytest.raises(InputError, match="calibration.toml"):
        load_marker_capture(tmp_path / "nowhere")


def test_make_scene_writes_a_marker_capture_without_videos(tmp_path):
    import subprocess
    import sys

    root = Path(__file__).resolve().parents[2]
    spec = tmp_path / "walk.toml"
    spec.write_text((root / "datasets_synthetic" / "markers_walk.toml").read_text().replace("frames = 300",
                                                                                           "frames = 20"))
    r = subprocess.run([sys.executable, str(root / "recipes" / "make_scene.py"), str(spec), "--out",
                        str(tmp_path / "out")], capture_output=True, text=True, cwd=root)
    assert r.returncode == 0, r.stderr
    assert "marker capture" in r.stdout
    cap = load_marker_capture(tmp_path / "out")
    assert cap.n_frames == 20 and len(cap.rig) == 8
    assert (tmp_path / "out" / "scene.rrd").is_file() and not (tmp_path / "out" / "videos").exists()
