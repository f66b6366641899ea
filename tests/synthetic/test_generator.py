"""The synthetic scene generator: determinism and exact ground truth."""

from __future__ import annotations

import json

import numpy as np
import pytest

from toolkit.anthropometry import AnthropometricConstraints
from toolkit.io import Dataset
from toolkit.synthetic import build_scene, parse_spec
from tests.synthetic.conftest import TINY_SPEC

#: GT 2D joints are the projections of GT 3D joints: only float32/npz rounding separates them.
REPROJECTION_TOL_PX = 0.01
#: Depth PNGs are whole millimetres.
DEPTH_TOL_M = 0.0006


def test_same_seed_same_scene_different_seed_differs():
    a = build_scene(parse_spec(TINY_SPEC))
    b = build_scene(parse_spec(TINY_SPEC))
    c = build_scene(parse_spec(TINY_SPEC.replace("seed = 11", "seed = 12")))
    np.testing.assert_array_equal(a.joints, b.joints)
    for ca, cb in zip(a.measured_rig, b.measured_rig):
        np.testing.assert_array_equal(ca.cam_from_world, cb.cam_from_world)
    np.testing.assert_array_equal(a.body_mesh(1).colors, b.body_mesh(1).colors)
    assert not np.allclose(a.joints, c.joints)


def test_images_identical_for_same_seed(tiny_dataset, tmp_path):
    from toolkit.synthetic import generate_scene
    again = generate_scene(parse_spec(TINY_SPEC), tmp_path / "again", progress=False)
    first = Dataset.open(tiny_dataset)
    for cam in first.camera_names:
        np.testing.assert_array_equal(first.gt_parts(cam, 2), again.gt_parts(cam, 2))
        assert np.abs(first.frame(cam, 1).astype(int) - again.frame(cam, 1).astype(int)).max() <= 1


def test_ground_truth_consistency(tiny_dataset):
    ds = Dataset.open(tiny_dataset)
    j3 = ds.gt_joints3d()
    j2 = ds.gt_joints2d()
    assert j3.shape == (3, 14, 3)
    for cam in ds.gt_rig:
        err = np.linalg.norm(cam.project(j3) - j2[cam.name], axis=-1)
        assert err.max() < REPROJECTION_TOL_PX
        for t in range(ds.n_frames):
            mask, parts, depth = ds.gt_mask(cam.name, t), ds.gt_parts(cam.name, t), ds.gt_depth(cam.name, t)
            assert mask.sum() > 50
            assert not np.any((parts > 0) & ~mask)          # every labelled pixel inside the mask
            assert np.all(parts[mask] > 0)                 # and the mask is exactly the labelled pixels
            assert set(np.unique(parts)) <= set(range(11))
            # depth of the body matches the camera-frame depth of nearby joints
            zs = cam.depth_of(j3[t])
            dz = depth[mask]
            assert zs.min() - 0.4 < np.nanmedian(dz) < zs.max() + 0.4
            # every joint projects inside (or right next to) the silhouette
            uv = np.round(j2[cam.name][t]).astype(int)
            inside = mask[np.clip(uv[:, 1], 0, mask.shape[0] - 1), np.clip(uv[:, 0], 0, mask.shape[1] - 1)]
            assert inside.mean() > 0.7


def test_depth_agrees_with_backprojection(tiny_dataset):
    """Back-projected GT depth of body pixels lands on the body (within its radius of a bone)."""
    from toolkit.skeleton import SKELETON_14
    ds = Dataset.open(tiny_dataset)
    cam = ds.gt_rig[0]
    depth, parts = ds.gt_depth(cam.name, 0), ds.gt_parts(cam.name, 0)
    v, u = np.nonzero(parts > 0)
    X = cam.backproject(np.stack([u, v], -1).astype(float), depth[v, u])
    ends = SKELETON_14.part_endpoints(ds.gt_joints3d()[0])
    a, b = ends[parts[v, u] - 1, 0], ends[parts[v, u] - 1, 1]
    ab = b - a
    s = np.clip(((X - a) * ab).sum(-1) / (ab * ab).sum(-1), 0, 1)
    dist = np.linalg.norm(X - (a + s[:, None] * ab), axis=-1)
    assert np.median(dist) < 0.12 and np.percentile(dist, 95) < 0.25


def test_calibration_error_reached(tiny_dataset):
    ds = Dataset.open(tiny_dataset)
    info = json.loads((tiny_dataset / "groundtruth" / "scene_info.json").read_text())
    j3 = ds.gt_joints3d()
    for meas, true in zip(ds.rig, ds.gt_rig):
        err = np.linalg.norm(meas.project(j3) - true.project(j3), axis=-1).mean()
        assert err == pytest.approx(4.0, rel=0.02)
        assert info["calibration_error_px"][true.name] == pytest.approx(err, rel=1e-6)


def test_subject_sizes_and_anthropometry():
    spec = parse_spec(TINY_SPEC.replace("[320, 180]", "[1280, 720]"))
    sc = build_scene(spec)
    from toolkit.synthetic.generator import _subject_heights_px
    h = _subject_heights_px(sc.rig, sc.joints)
    # joints span ankle to head centre (~0.9 of stature): 100-250 px people give 85-235 px joint spans
    assert all(80 <= v <= 250 for v in h), h
    checker = AnthropometricConstraints()
    assert all(checker.is_valid(j) for j in sc.joints)


def test_novel_views_written(tiny_dataset):
    ds = Dataset.open(tiny_dataset)
    cam = ds.novel_rig[0]
    img, mask, parts = ds.novel_image(cam.name, 0), ds.novel_mask(cam.name, 0), ds.novel_parts(cam.name, 0)
    assert img.shape == (180, 320, 3) and mask.any() and not np.any((parts > 0) & ~mask)
    # the novel camera is not one of the source cameras
    assert min(np.linalg.norm(cam.center - c.center) for c in ds.gt_rig) > 5.0


def test_rendered_image_matches_mask(tiny_dataset):
    """The subject is where the mask says: colours differ from the background plate only near the mask."""
    import cv2
    ds = Dataset.open(tiny_dataset)
    cam = ds.camera_names[0]
    f0, f2 = ds.frame(cam, 0).astype(int), ds.frame(cam, 2).astype(int)
    m0, m2 = ds.gt_mask(cam, 0), ds.gt_mask(cam, 2)
    changed = np.abs(f0 - f2).sum(-1) > 60
    near = cv2.dilate((m0 | m2).astype(np.uint8), np.ones((5, 5), np.uint8)) > 0
    assert changed.sum() > 20
    assert (changed & ~near).sum() <= 0.02 * changed.sum()


@pytest.mark.timeout(240)
def test_open3d_and_raycast_renderers_agree():
    """Open3D's off-screen rasteriser and the ray-cast renderer give the same picture."""
    from toolkit.synthetic import make_environment
    from toolkit.synthetic.environment import BACKGROUND_COLOUR
    from toolkit.synthetic.render import RaycastRenderer, SceneRenderer
    spec = parse_spec(TINY_SPEC.replace("[320, 180]", "[160, 90]"))
    sc = build_scene(spec)
    env = make_environment("broadcast", 0)
    mesh = sc.body_mesh(0)
    cam = sc.rig[0]
    images = []
    for r in (SceneRenderer(cam.size, env, BACKGROUND_COLOUR["broadcast"], 1),
              RaycastRenderer(cam.size, env, BACKGROUND_COLOUR["broadcast"], 1)):
        r.set_bodies([(mesh, mesh.shaded_colors(sc.light_dir))])
        images.append(r.render(cam).astype(int))
    diff = np.abs(images[0] - images[1]).mean(-1)
    # textures are filtered differently (Open3D mip-maps, the ray caster samples bilinearly)
    assert np.median(diff) < 12


def test_depth_camera_table_writes_depth_sequence(tmp_path):
    """A ``[depth_camera]`` table makes the generator write the depth camera and the 13/17-point truth."""
    from toolkit.synthetic import generate_scene
    text = TINY_SPEC.replace("frames = 3", "frames = 2") + "\n[depth_camera]\nresolution = [160, 120]\nnoise = true\n"
    generate_scene(parse_spec(text, "depth.toml"), tmp_path / "d", progress=False).close()
    root = tmp_path / "d"
    assert (root / "depth_camera" / "intrinsics.toml").is_file()
    assert sorted(p.name for p in (root / "depth_camera" / "depth").iterdir()) == ["000000.png", "000001.png"]
    s13 = np.load(root / "groundtruth" / "skeleton13.npz")
    assert s13["joints"].shape == (2, 13, 3) and len(s13["names"]) == 13
    assert np.load(root / "groundtruth" / "skeleton17.npz")["joints"].shape == (2, 17, 3)


def test_clean_plates_written(tiny_dataset):
    """``background/<camera>.png`` is the empty scene: equal to the frame wherever the subject is absent."""
    ds = Dataset.open(tiny_dataset)
    for cam in ds.camera_names:
        plate = ds.background(cam).astype(int)
        frame = ds.frame(cam, 0).astype(int)
        away = ~ds.gt_mask(cam, 0)
        import cv2
        away &= cv2.dilate((~away).astype(np.uint8), np.ones((7, 7), np.uint8)) == 0
        # mp4v compression of the grass texture: ~5 levels per channel (measured 14 summed over RGB)
        assert np.median(np.abs(plate - frame).sum(-1)[away]) < 24
        assert np.median(np.abs(plate - frame).sum(-1)[ds.gt_mask(cam, 0)]) > 60
