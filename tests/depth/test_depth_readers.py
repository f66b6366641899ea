"""Depth readers and the depth camera's intrinsics file."""

from __future__ import annotations

import numpy as np
import pytest

from toolkit.cameras import Camera
from toolkit.io.depth_readers import (
    KINECT_V1_FOCAL_PX,
    default_depth_camera,
    depth_intrinsics_text,
    list_depth_frames,
    read_depth,
    read_depth_intrinsics,
    read_depth_raw,
)
from toolkit.errors import InputError
from toolkit.io import atomic_write_png, depth_to_mm

#: uint16 millimetres round to the nearest millimetre.
MM_TOLERANCE_M = 0.0005


def _depth(h=6, w=8, seed=0):
    rng = np.random.default_rng(seed)
    d = rng.uniform(0.6, 4.0, (h, w)).astype(np.float32)
    d[0, 0] = np.nan
    return d


def test_png_round_trip(tmp_path):
    d = _depth()
    p = tmp_path / "000000.png"
    atomic_write_png(p, depth_to_mm(d))
    back = read_depth(p)
    assert back.dtype == np.float32 and back.shape == d.shape
    assert np.isnan(back[0, 0])
    np.testing.assert_allclose(back[1:], d[1:], atol=MM_TOLERANCE_M)


def test_raw_little_endian_uint16(tmp_path):
    mm = np.arange(12, dtype="<u2").reshape(3, 4) * 100
    p = tmp_path / "frame-raw"
    mm.tofile(p)
    d = read_depth(p, size=(4, 3))
    assert np.isnan(d[0, 0])
    np.testing.assert_allclose(d[2, 3], 1.1, atol=1e-6)
    with pytest.raises(InputError, match="bytes"):
        read_depth_raw(p, size=(5, 3))


def test_open3d_and_npy_readers(tmp_path):
    d = _depth()
    np.save(tmp_path / "d.npy", d)
    np.testing.assert_allclose(read_depth(tmp_path / "d.npy")[1:], d[1:])
    import open3d as o3d

    p = tmp_path / "d16.png"
    o3d.io.write_image(str(p), o3d.geometry.Image(depth_to_mm(d)))
    back = read_depth(p, reader="open3d")
    np.testing.assert_allclose(back[1:], d[1:], atol=MM_TOLERANCE_M)
    with pytest.raises(InputError, match="reader"):
        read_depth(p, reader="jpeg2000")


def test_missing_file_names_the_path(tmp_path):
    with pytest.raises(InputError, match="no such file"):
        read_depth(tmp_path / "nothing.png")


def test_list_depth_frames_natural_order(tmp_path):
    for n in ("depth-10", "depth-9", "depth-100", "intrinsics.toml", ".hidden"):
        (tmp_path / n).write_bytes(b"x")
    assert [p.name for p in list_depth_frames(tmp_path)] == ["depth-9", "depth-10", "depth-100"]
    with pytest.raises(InputError):
        list_depth_frames(tmp_path / "missing")


def test_default_camera_is_kinect_like():
    cam = default_depth_camera()
    assert cam.size == (640, 480)
    assert cam.K[0, 0] == KINECT_V1_FOCAL_PX
    assert default_depth_camera((320, 240)).K[0, 0] == pytest.approx(KINECT_V1_FOCAL_PX / 2)
    fov = 2 * np.degrees(np.arctan(320 / KINECT_V1_FOCAL_PX))
    assert 56 < fov < 59  # Kinect v1: about 57 degrees


def test_intrinsics_round_trip(tmp_path):
    cam = Camera.look_at("depth", [0.3, 3.0, 1.1], [0, 0, 0.9], size=(320, 240), fov_x_deg=57)
    p = tmp_path / "intrinsics.toml"
    p.write_text(depth_intrinsics_text(cam))
    info = read_depth_intrinsics(p)
    assert info.pose_known and info.camera.size == (320, 240)
    np.testing.assert_array_equal(info.camera.K, cam.K)
    np.testing.assert_allclose(info.camera.cam_from_world, cam.cam_from_world, atol=1e-15)
    p.write_text(depth_intrinsics_text(cam, pose_known=False))
    assert not read_depth_intrinsics(p).pose_known


@pytest.mark.parametrize("text, field", [
    ('size = [320]\nmatrix = [[1,0,0],[0,1,0],[0,0,1]]\n', "size"),
    ('size = [320, 240]\n', "matrix"),
    ('size = [320, 240]\nmatrix = [[1,0,0],[0,1,0]]\n', "matrix"),
    ('size = [320, 240]\nmatrix = [[1,0,0],[0,1,0],[0,0,1]]\ncam_from_world = [[1,0],[0,1]]\n', "cam_from_world"),
    ('size = [320, 240\n', "valid TOML"),
])
def test_intrinsics_errors_name_the_field(tmp_path, text, field):
    p = tmp_path / "intrinsics.toml"
    p.write_text(text)
    with pytest.raises(InputError, match=field):
        read_depth_intrinsics(p)


def test_real_kinect_frames_read(kinect_dir):
    files = list_depth_frames(kinect_dir)
    assert len(files) == 12
    d = read_depth(files[0])
    assert d.shape == (480, 640)
    valid = d[np.isfinite(d)]
    # background removed: 10-20 % of the pixels hold the person at 0.7-2 m
    assert 0.05 < valid.size / d.size < 0.4
    assert 0.6 < np.median(valid) < 2.0
