"""Stereo clouds of a trinocular head (issue 18): close to the true body surface, checked by the third camera."""

from pathlib import Path

import numpy as np
import pytest

from toolkit.errors import InputError
from toolkit.io import Dataset
from toolkit.pointcloud.stereo import (StereoConfig, head_cloud, head_pairs, rotated_camera, trinocular_heads)
from toolkit.synthetic.generator import build_scene, generate_scene
from toolkit.synthetic.spec import parse_spec

SPEC = """seed = 5
frames = 1
fps = 25
[subject]
height_m = 1.74
motion = "idle"
pattern = "checks"
[cameras]
count = 3
layout = "trinocular"
baseline_m = [0.3, 0.35]
resolution = [320, 240]
"""


@pytest.fixture(scope="module")
def trinocular_frame(tmp_path_factory):
    spec = parse_spec(SPEC, "test_stereo")
    out = tmp_path_factory.mktemp("tri")
    generate_scene(spec, out, progress=False)
    return Dataset.open(out), build_scene(spec)


def _surface_distance(points, mesh):
    import open3d as o3d

    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(o3d.core.Tensor(mesh.vertices.astype(np.float32)),
                        o3d.core.Tensor(mesh.triangles.astype(np.uint32)))
    return scene.compute_distance(o3d.core.Tensor(points.astype(np.float32))).numpy()


def test_stereo_cloud_lies_on_the_true_surface(trinocular_frame):
    data, scene = trinocular_frame
    (head,) = trinocular_heads(data.rig)
    images = [data.frame(c.name, 0) for c in head]
    masks = [data.gt_mask(c.name, 0) for c in head]
    cloud = head_cloud(images, head, masks)
    d = _surface_distance(cloud.points, scene.body_mesh(0))
    assert len(cloud.points) > 1000
    assert np.median(d) < 0.025
    assert np.percentile(d, 90) < 0.06


def test_third_camera_removes_the_background_matches(trinocular_frame):
    data, scene = trinocular_frame
    (head,) = trinocular_heads(data.rig)
    images = [data.frame(c.name, 0) for c in head]
    loose = head_cloud(images, head, None, StereoConfig(agreement_px=1e6))  # no mask, (almost) no check
    strict = head_cloud(images, head, None, StereoConfig(agreement_px=1.0))
    # without a mask the cloud is the whole studio; what the check removes is the matches that disagree
    mesh = scene.body_mesh(0)
    far = lambda pts: np.mean(_surface_distance(pts, mesh) > 0.2)  # noqa: E731
    assert len(strict.points) < len(loose.points)
    assert np.mean(np.abs(strict.points[:, 2]) < 10) == 1.0
    assert strict.n_matched == loose.n_matched
    # the walls are true surfaces too, matched alike by both pairs: since SGBM's dead band is padded away
    # (the vertical pair covers the whole picture) the check keeps them, and removes what disagrees
    assert far(strict.points) <= far(loose.points) + 0.02


def test_rotated_camera_turns_pixels():
    from toolkit.cameras import Camera

    cam = Camera.look_at("c", [3.0, 0.5, 1.2], [0.0, 0.0, 1.0], size=(320, 240), focal_px=300.0)
    pts = np.random.default_rng(0).uniform([-0.5, -0.5, 0.2], [0.5, 0.5, 1.8], (20, 3))
    uv = cam.project(pts)
    uvr = rotated_camera(cam).project(pts)
    assert np.allclose(uvr, np.stack([239 - uv[:, 1], uv[:, 0]], axis=1), atol=1e-9)
    ph, pv = head_pairs([cam, cam.replace(name="r", cam_from_world=_shifted(cam, [0.3, 0, 0])),
                         cam.replace(name="u", cam_from_world=_shifted(cam, [0, -0.3, 0]))])
    assert ph.baseline_m == pytest.approx(0.3) and pv.baseline_m == pytest.approx(0.3)


def _shifted(cam, offset_cam):
    T = np.array(cam.cam_from_world)
    T[:3, 3] -= np.asarray(offset_cam)  # the camera moved by offset_cam along its own axes
    return T


def test_not_a_trinocular_rig():
    from toolkit.cameras import Camera, Rig

    cam = Camera.look_at("c", [3.0, 0.0, 1.2], [0.0, 0.0, 1.0], size=(320, 240), focal_px=300.0)
    with pytest.raises(InputError, match="3 cameras per trinocular head"):
        trinocular_heads(Rig((cam,)))
    left = cam.replace(name="l", cam_from_world=_shifted(cam, [-0.3, 0, 0]))
    with pytest.raises(InputError, match="trinocular head"):
        trinocular_heads(Rig((cam, left, cam.replace(name="u"))))
    with pytest.raises(InputError, match="block_size"):
        StereoConfig(block_size=4)
